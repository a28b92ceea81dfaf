// The live preview (/?job=JOBID): a live body job's fitted poses as they
// come, over a WebSocket to /api/v1/jobs/JOBID/follow, with the latency
// from capture to this screen. Reconnects with backoff while the job runs.

import { MeshLambertMaterial } from 'three';
import { ApiError, apiJson, describeError, webSocketUrl } from './api.js';
import { analyseMotion, parseGlb } from './model.js';
import { backgroundFromParams } from './player.js';
import { Stage } from './stage.js';
import { clearError, h, setState, setStatus, showError } from './ui.js';

const FINAL_CODES = new Set([
  'NOT_FOUND',
  'INVALID_ARGUMENT',
  'PERMISSION_DENIED',
  'UNAUTHENTICATED',
  'FAILED_PRECONDITION',
]);

function percentile(values, p) {
  if (!values.length) return null;
  const sorted = [...values].sort((a, b) => a - b);
  const i = Math.min(sorted.length - 1, Math.max(0, Math.ceil((p / 100) * sorted.length) - 1));
  return sorted[i];
}

export function startLive(jobId, params) {
  setState('loading');
  document.body.classList.add('page-live');
  const stageEl = h('div', { id: 'stage', class: 'stage' });
  const title = h('h1', { id: 'title' }, 'Live');
  const subtitle = h('p', { id: 'subtitle', class: 'subtitle' }, jobId);
  const latencyLabel = h('output', { id: 'latency', class: 'big-figure' }, '– ms');
  const framesLabel = h('output', { id: 'live-frames', class: 'time' }, '');
  const fpsLabel = h('output', { id: 'live-fps', class: 'time' }, '');
  const mirrorButton = h('button', { class: 'btn toggle', id: 'mirror', type: 'button', 'aria-pressed': 'false' }, 'Mirror');
  const floorButton = h('button', { class: 'btn toggle', id: 'floor', type: 'button', 'aria-pressed': 'false' }, 'Floor');
  const yawSlider = h('input', { id: 'yaw', type: 'range', min: '-180', max: '180', step: '1', value: '0', 'aria-label': 'Turn' });
  const yawLabel = h('output', { id: 'yaw-value', class: 'time' }, '0°');
  const faceMe = h('button', { class: 'btn', id: 'face-me', type: 'button' }, 'Face me');
  const resetView = h('button', { class: 'btn', id: 'reset-view', type: 'button' }, 'Reset view');
  const fullscreen = h('button', { class: 'btn', id: 'fullscreen', type: 'button' }, 'Fullscreen');
  const afterwards = h('p', { id: 'afterwards', class: 'note', hidden: true });
  const hud = h(
    'div',
    { id: 'hud', class: 'hud' },
    h('div', { class: 'row readout' }, h('span', { class: 'label' }, 'Capture → screen'), latencyLabel, framesLabel, fpsLabel),
    h(
      'div',
      { class: 'row' },
      mirrorButton,
      floorButton,
      h('label', { class: 'field yaw' }, 'Turn ', yawSlider, yawLabel),
      faceMe,
      resetView,
      fullscreen,
    ),
    afterwards,
  );
  stageEl.append(
    h(
      'header',
      { class: 'topbar' },
      h('a', { class: 'btn back', href: './', 'aria-label': 'Back to the library' }, '‹ Library'),
      h('div', { class: 'titles' }, title, subtitle),
    ),
  );
  document.getElementById('app').append(stageEl, hud);
  if (params.get('controls') === '0') document.body.classList.add('no-controls');

  // The preview redraws at the capture's pace while the server fits on the
  // same machine or network: no multisampling (high-density screens hardly
  // need it), and the grey body gets a cheap diffuse material.
  const stage = new Stage(stageEl, {
    background: backgroundFromParams(params, '#1b1f24'),
    antialias: (window.devicePixelRatio || 1) >= 2 && params.get('aa') !== '0',
    floor: params.get('floor') !== '0',
  });
  const live = {
    frames_received: 0,
    first_frame_index: null,
    last_frame_index: null,
    latencies_ms: [],
    // Its parts: on the server (FrameSet arrived -> fitted frame published)
    // and from the server's send to this page's handler.
    server_ms: [],
    delivery_ms: [],
    fit_ms: [],
    reconnects: 0,
    ended: false,
    end: null,
  };
  let latest = null; // the latest frame message
  let pendingPose = null; // a frame that came while the model was being read
  let bones = null;
  let framed = false;
  let meshBytes = null; // the mesh message announcing the next binary one
  let modelLoads = Promise.resolve();
  let socket = null;
  let failures = 0;
  let retryTimer = 0;

  window.reenactStats = () => ({
    fps: stage.fps(),
    frame: latest ? latest.frame_index : 0,
    frames: live.frames_received,
    latency_ms: latest ? latest.latency_ms : null,
  });
  window.reenactCamera = () => stage.cameraInfo();
  window.reenactLive = () => ({
    ...live,
    latencies_ms: [...live.latencies_ms],
    server_ms: [...live.server_ms],
    delivery_ms: [...live.delivery_ms],
    fit_ms: [...live.fit_ms],
  });

  const setYaw = (deg) => {
    const d = stage.setYaw(deg);
    yawSlider.value = String(Math.round(d));
    yawLabel.textContent = `${Math.round(d)}°`;
  };
  const setMirror = (on) => {
    stage.setMirror(on);
    mirrorButton.setAttribute('aria-pressed', on ? 'true' : 'false');
  };
  const setFloor = (on) => {
    floorButton.setAttribute('aria-pressed', stage.setFloor(on) ? 'true' : 'false');
  };
  mirrorButton.addEventListener('click', () => setMirror(!stage.mirror));
  floorButton.addEventListener('click', () => setFloor(!stage.floor.visible));
  yawSlider.addEventListener('input', () => setYaw(Number(yawSlider.value)));
  faceMe.addEventListener('click', () => setYaw(stage.faceCameraYaw()));
  resetView.addEventListener('click', () => stage.resetView());
  if (!document.fullscreenEnabled) fullscreen.disabled = true;
  fullscreen.addEventListener('click', () => {
    if (document.fullscreenElement) document.exitFullscreen();
    else document.documentElement.requestFullscreen().catch(() => {});
  });
  setMirror(params.get('mirror') === '1');
  setFloor(params.get('floor') !== '0');
  if (params.has('yaw')) setYaw(Number(params.get('yaw')) || 0);

  // The job, for the title and for 401/403/404 answers a WebSocket cannot
  // give.
  async function lookUpJob() {
    const jobs = await apiJson('/api/v1/jobs');
    const job = Array.isArray(jobs) ? jobs.find((j) => j.id === jobId) : null;
    if (job) {
      title.textContent = `Live: ${job.take_id}`;
      subtitle.textContent = `${job.method} · ${job.state}${job.stage ? ` · ${job.stage}` : ''}`;
    }
    return job;
  }

  function pose(message) {
    if (!bones) return;
    const rotations = message.local_rotations || [];
    const n = Math.min(bones.length, rotations.length);
    for (let j = 0; j < n; ++j) {
      const q = rotations[j];
      bones[j].quaternion.set(q[0], q[1], q[2], q[3]);
    }
    const root = message.root_position_m;
    if (root && bones[0]) bones[0].position.set(root[0], root[1], root[2]);
    if (!framed) {
      framed = true;
      frameActor();
    }
    stage.invalidate();
  }

  // Frames the actor as posed now, with room for it to move.
  function frameActor() {
    if (!stage.model) return;
    const motion = analyseMotion(stage.model, null, 1);
    motion.extent.expandByVector({ x: 0.3, y: 0.05, z: 0.3 });
    stage.setModel(stage.model, motion);
    stage.frame(motion);
  }

  function loadMesh(buffer) {
    modelLoads = modelLoads.then(async () => {
      try {
        const { gltf } = await parseGlb(buffer);
        let skinned = null;
        gltf.scene.traverse((o) => {
          if (o.isSkinnedMesh && !skinned) skinned = o;
        });
        if (!skinned) throw new Error('the live mesh has no skin');
        const old = skinned.material;
        if (old && !old.map) {
          skinned.material = new MeshLambertMaterial({ color: old.color ? old.color.clone() : 0xb0b0b0 });
          old.dispose();
        }
        const replacing = stage.model !== null;
        bones = skinned.skeleton.bones;
        const motion = analyseMotion(gltf.scene, null, 1);
        stage.setModel(gltf.scene, motion);
        if (!replacing) stage.frame(motion);
        framed = replacing;
        const p = pendingPose || latest;
        pendingPose = null;
        if (p) pose(p);
      } catch (e) {
        setStatus(`The live mesh could not be read: ${describeError(e)}`);
      }
    });
  }

  function onFrame(m) {
    const latency = Date.now() - Number(m.arrived_unix_ns) / 1e6;
    m.latency_ms = latency;
    latest = m;
    live.frames_received += 1;
    if (live.first_frame_index === null) live.first_frame_index = m.frame_index;
    live.last_frame_index = m.frame_index;
    live.latencies_ms.push(Math.round(latency * 10) / 10);
    live.server_ms.push(Math.round((Number(m.published_unix_ns) - Number(m.arrived_unix_ns)) / 1e5) / 10);
    live.fit_ms.push(Math.round(Number(m.fit_ms) * 10) / 10);
    live.delivery_ms.push(Math.round((Date.now() - Number(m.sent_unix_ns) / 1e6) * 10) / 10);
    if (bones) pose(m);
    else pendingPose = m;
    if (document.body.dataset.state !== 'playing') {
      clearError();
      setStatus('');
      setState('playing');
    }
  }

  function onEnd(m) {
    clearError();
    live.ended = true;
    live.end = m;
    const why = m.reason === 'take_complete' ? 'The take is complete' : `The live preview ended (${m.reason})`;
    setStatus(`${why}${m.message ? `: ${m.message}` : ''}. ${live.frames_received} frames shown here.`);
    setState('ready');
    showAfterwards();
  }

  async function showAfterwards() {
    try {
      const job = await lookUpJob();
      if (job && job.reenactment_id) {
        afterwards.replaceChildren(
          'The reenactment: ',
          h('a', { class: 'btn', href: `?reenactment=${encodeURIComponent(job.reenactment_id)}` }, 'Open'),
        );
        afterwards.hidden = false;
      } else if (job) {
        afterwards.textContent = `The job goes on (${job.state}${job.stage ? `, ${job.stage}` : ''}); its reenactment will be in the library.`;
        afterwards.hidden = false;
        if (job.state === 'running' || job.state === 'queued') setTimeout(showAfterwards, 3000);
      }
    } catch {
      // The page already says the preview ended.
    }
  }

  function connect() {
    clearTimeout(retryTimer);
    let url;
    try {
      url = webSocketUrl(`/api/v1/jobs/${encodeURIComponent(jobId)}/follow`);
      socket = new WebSocket(url);
    } catch (e) {
      showError(`Cannot open the live connection: ${e.message || e}`);
      return;
    }
    socket.binaryType = 'arraybuffer';
    const ws = socket;
    let opened = false;
    let finalError = false;
    ws.addEventListener('open', () => {
      opened = true;
      failures = 0;
      setStatus(live.reconnects ? 'Reconnected; waiting for frames…' : 'Connected; waiting for frames…');
    });
    ws.addEventListener('message', (event) => {
      if (typeof event.data !== 'string') {
        if (meshBytes !== null) {
          meshBytes = null;
          loadMesh(event.data);
        }
        return;
      }
      let m;
      try {
        m = JSON.parse(event.data);
      } catch {
        return;
      }
      if (m.type === 'frame') onFrame(m);
      else if (m.type === 'mesh') meshBytes = m.bytes;
      else if (m.type === 'end') onEnd(m);
      else if (m.type === 'error') {
        if (FINAL_CODES.has(m.code)) {
          finalError = true;
          live.ended = true;
          live.end = m;
          showError(`${m.code}: ${m.message}`);
        } else {
          setStatus(`The server reports ${m.code}: ${m.message}`);
        }
      }
    });
    ws.addEventListener('close', (event) => {
      if (socket !== ws) return;
      socket = null;
      if (live.ended || finalError) return;
      scheduleReconnect(opened ? `The connection dropped (code ${event.code}${event.reason ? `, ${event.reason}` : ''}).` : 'The live connection could not be opened.');
    });
  }

  async function scheduleReconnect(what) {
    ++failures;
    const delay = Math.min(10000, 500 * 2 ** Math.min(failures - 1, 5));
    setStatus(`${what} Reconnecting in ${(delay / 1000).toFixed(1)} s…`);
    retryTimer = setTimeout(async () => {
      try {
        const job = await lookUpJob();
        if (job && job.state !== 'running' && job.state !== 'queued') {
          live.ended = true;
          setStatus(`The job is ${job.state}; the live preview is over.`);
          setState('ready');
          showAfterwards();
          return;
        }
        if (!job) {
          showError(`No job ${jobId} on this server.`);
          return;
        }
      } catch (e) {
        if (e instanceof ApiError && (e.status === 401 || e.status === 403)) {
          showError(e);
          return;
        }
        showError(`The live connection is lost. ${describeError(e)} Retrying…`, {
          retry: () => {
            failures = 0;
            clearTimeout(retryTimer);
            live.reconnects += 1;
            connect();
          },
          retryLabel: 'Reconnect now',
        });
        scheduleReconnect('The server cannot be reached.');
        return;
      }
      live.reconnects += 1;
      connect();
    }, delay);
  }

  // Figures on screen, four times a second.
  setInterval(() => {
    if (latest) {
      const recent = live.latencies_ms.slice(-30);
      latencyLabel.textContent = `${Math.round(latest.latency_ms)} ms`;
      latencyLabel.title = `median of the last ${recent.length}: ${Math.round(percentile(recent, 50))} ms`;
      framesLabel.textContent = `frame ${latest.frame_index} · ${live.frames_received} received${live.reconnects ? ` · ${live.reconnects} reconnects` : ''}`;
    }
    fpsLabel.textContent = `${stage.fps()} fps`;
  }, 250);

  setStatus('Connecting…');
  lookUpJob()
    .then((job) => {
      if (!job) setStatus(`The server lists no job ${jobId}; asking it anyway…`);
    })
    .catch((e) => {
      if (e instanceof ApiError && (e.status === 401 || e.status === 403)) {
        showError(e);
        if (socket) socket.close();
        live.ended = true;
      }
    });
  connect();
}
