// The live preview (/?job=JOBID): a live body job's fitted poses as they
// come, over a WebSocket to /api/v1/jobs/JOBID/follow, with the latency
// from capture to this screen. Reconnects with backoff while the job runs.

import { isAccessError } from './lib/errors.js';
import {
  createLiveRecord,
  endText,
  framesReadout,
  percentile,
  recordFrame,
  snapshotRecord,
} from './lib/live-record.js';
import { backgroundFromParams, viewParams } from './lib/params.js';
import { LiveBody } from './live/body.js';
import { LiveConnection } from './live/connection.js';
import { lookUpJob, showAfterwards } from './live/job.js';
import { createLiveLayout } from './live/layout.js';
import { Stage } from './stage.js';
import { clearError, getState, setState, setStatus, showError } from './ui.js';
import { bindViewControls } from './view-controls.js';

// The hooks tests read: reenactStats(), reenactCamera(), reenactLive().
function installHooks(stage, record, body) {
  window.reenactStats = () => ({
    fps: stage.fps(),
    frame: body.latest ? body.latest.frame_index : 0,
    frames: record.frames_received,
    latency_ms: body.latest ? body.latest.latency_ms : null,
  });
  window.reenactCamera = () => stage.cameraInfo();
  window.reenactLive = () => snapshotRecord(record);
}

// The readouts, four times a second.
function showFigures(layout, stage, record, body) {
  setInterval(() => {
    const latest = body.latest;
    if (latest) {
      const recent = record.latencies_ms.slice(-30);
      layout.latencyLabel.textContent = `${Math.round(latest.latency_ms)} ms`;
      layout.latencyLabel.title = `median of the last ${recent.length}: ${Math.round(percentile(recent, 50))} ms`;
      layout.framesLabel.textContent = framesReadout(latest.frame_index, record);
    }
    layout.fpsLabel.textContent = `${stage.fps()} fps`;
  }, 250);
}

// The preview redraws at the capture's pace while the server fits on the
// same machine or network: no multisampling (high-density screens hardly
// need it).
function createStage(layout, params, floor) {
  return new Stage(layout.stageEl, {
    background: backgroundFromParams(params, '#1b1f24'),
    antialias: (window.devicePixelRatio || 1) >= 2 && params.get('aa') !== '0',
    floor,
  });
}

// The view's controls, set from the address (&mirror, &floor, &yaw).
function setUpView(stage, layout, view, params) {
  const { setYaw, setMirror, setFloor } = bindViewControls(stage, layout);
  setMirror(view.mirror);
  setFloor(view.floor);
  if (params.has('yaw')) setYaw(Number(params.get('yaw')) || 0);
}

// What the page does with the connection's news: frames pose the body,
// the end says why and links what follows.
function liveHandlers({ record, body, layout, lookUp }) {
  const afterwards = () => showAfterwards(lookUp, layout.afterwards);
  return {
    frame: (m) => {
      recordFrame(record, m, Date.now());
      body.receive(m);
      if (getState() !== 'playing') {
        clearError();
        setStatus('');
        setState('playing');
      }
    },
    mesh: (buffer) => body.loadMesh(buffer),
    end: (m) => {
      clearError();
      record.ended = true;
      record.end = m;
      setStatus(endText(m, record.frames_received));
      setState('ready');
      afterwards();
    },
    over: afterwards,
  };
}

export function startLive(jobId, params) {
  setState('loading');
  const view = viewParams(params);
  const layout = createLiveLayout(jobId, view.controls);
  const stage = createStage(layout, params, view.floor);
  const record = createLiveRecord();
  const body = new LiveBody(stage);
  installHooks(stage, record, body);
  setUpView(stage, layout, view, params);

  const lookUp = () => lookUpJob(jobId, layout);
  const on = liveHandlers({ record, body, layout, lookUp });
  const connection = new LiveConnection({ jobId, record, lookUp, on });
  showFigures(layout, stage, record, body);
  setStatus('Connecting…');
  lookUp()
    .then((job) => {
      if (!job) setStatus(`The server lists no job ${jobId}; asking it anyway…`);
    })
    .catch((e) => {
      if (isAccessError(e)) {
        showError(e);
        connection.stop();
      }
    });
  connection.connect();
}
