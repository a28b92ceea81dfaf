// The player (/?reenactment=ID): the reenactment's glTF animation with
// play/pause, scrubbing, speed, an A-B loop, the mirror image, the
// teacher's turn, orbit/zoom/pan, fullscreen and AR placement.
//
// Deep link: &t=SECONDS &paused=1 &yaw=DEG &mirror=0|1 &speed=X &a=S&b=S
// &bg=RRGGBB &controls=0 (the view alone: kiosks, tests) &appearance=0 (the
// static atlas, not the per-frame appearance video) &floor=0 (no floor
// grid: pixel comparisons with `reenact render`, which draws none).

import { Appearance } from './appearance.js';
import { backgroundFromParams, playerParams } from './lib/params.js';
import { Playback } from './lib/playback.js';
import { frameTimes, timelineOf } from './lib/timeline.js';
import { analyseMotion } from './model.js';
import { applyDeepLink, bindPlayerControls, createPlayerActions, offerAr, runClock } from './player/controls.js';
import { createPlayerHud } from './player/hud.js';
import { createPlayerLayout, showTitle } from './player/layout.js';
import { createPoser, loadReenactment } from './player/load.js';
import { Stage } from './stage.js';
import { h, setState, setStatus } from './ui.js';

// The hooks tests and kiosks read: reenactStats(), reenactCamera(),
// reenactPlayer(). `session.appearance`: the appearance once loaded.
function installHooks(stage, playback, session) {
  window.reenactStats = () => ({
    fps: stage.fps(),
    frame: playback.frame,
    frames: playback.frames,
    latency_ms: null,
  });
  window.reenactCamera = () => stage.cameraInfo();
  window.reenactPlayer = () => ({
    time: playback.time,
    playing: playback.playing,
    speed: playback.speed,
    a: playback.a,
    b: playback.b,
    yaw_deg: stage.yawDeg,
    duration: playback.duration,
    length_s: playback.length,
    floor: stage.floor.visible,
    appearance: session.appearance ? session.appearance.stats() : null,
  });
}

// The body's per-frame appearance, drawn once its video has loaded (the
// static atlas until then, and where it cannot be); its note says which.
function startAppearance({ id, model, frames, fps, stage, enabled }) {
  const note = h('span', { id: 'appearance-note', class: 'note', role: 'status' }, '');
  const appearance = new Appearance({
    id,
    model,
    frames,
    fps,
    onChange: () => {
      note.textContent = appearance.note;
      stage.invalidate();
    },
  });
  if (!enabled) appearance.fallBack('per-frame appearance turned off (appearance=0)');
  else appearance.load();
  return { appearance, note };
}

export async function startPlayer(id, params) {
  setState('loading');
  const link = playerParams(params);
  const layout = createPlayerLayout(id, link.controls);
  const stage = new Stage(layout.stageEl, { background: backgroundFromParams(params, '#1b1f24'), floor: link.floor });
  const playback = new Playback();
  const session = { appearance: null };
  installHooks(stage, playback, session);
  showTitle(id, layout);

  const loaded = await loadReenactment(id, layout.loadingEl);
  if (!loaded) return;
  const { gltf, info } = loaded;
  const model = gltf.scene;
  const clip = gltf.animations[0] || null;
  const times = frameTimes(clip, info);
  const timeline = timelineOf(clip ? clip.duration : null, times, info.fps);
  playback.setTimeline({ times, duration: timeline.duration, length: timeline.length });
  const motion = analyseMotion(model, clip);
  stage.setModel(model, motion);
  stage.frame(motion);

  const { appearance, note } = startAppearance({
    id,
    model,
    frames: timeline.frames,
    fps: timeline.appearanceFps,
    stage,
    enabled: link.appearance,
  });
  session.appearance = appearance;
  const pose = createPoser(model, clip);
  const hud = createPlayerHud(layout.hud, playback.duration, note);
  const actions = createPlayerActions({ playback, stage, pose, hud });
  bindPlayerControls(hud, actions, playback);
  runClock({ stage, playback, actions, appearance });
  applyDeepLink(link, playback, actions);
  setStatus('');
  offerAr({ stage, hud, overlay: layout.overlay, motion, actions });
}
