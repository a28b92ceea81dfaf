// The player (/?reenactment=ID): the reenactment's glTF animation with
// play/pause, scrubbing, speed, an A-B loop, the mirror image, the
// teacher's turn, orbit/zoom/pan, fullscreen and AR placement.
//
// Deep link: &t=SECONDS &paused=1 &yaw=DEG &mirror=0|1 &speed=X &a=S&b=S
// &bg=RRGGBB &controls=0 (the view alone: kiosks, tests) &appearance=0 (the
// static atlas, not the per-frame appearance video) &floor=0 (no floor
// grid: pixel comparisons with `reenact render`, which draws none).

import { AnimationMixer, LoopRepeat } from 'three';
import { apiJson, fetchGlb } from './api.js';
import { Appearance } from './appearance.js';
import { setupAr } from './ar.js';
import { analyseMotion, frameTimes, nearestFrame, parseGlb } from './model.js';
import { Stage } from './stage.js';
import { cardTitle, clearError, formatSeconds, h, lengthSeconds, setState, setStatus, showError } from './ui.js';

const SPEEDS = [0.25, 0.5, 0.75, 1, 1.25, 1.5, 2];

export function backgroundFromParams(params, fallback) {
  const bg = (params.get('bg') || '').replace(/^#/, '');
  return /^[0-9a-fA-F]{6}$/.test(bg) ? `#${bg}` : fallback;
}

// Keys a focused control answers itself: Space and Enter press a button or
// follow a link, type into a field, move a slider, open a list. The page's
// shortcuts leave them alone there.
export function controlTakesKey(target, key) {
  if (!(target instanceof Element)) return false;
  if (target instanceof HTMLInputElement || target instanceof HTMLSelectElement || target instanceof HTMLTextAreaElement) {
    return true;
  }
  if (target.isContentEditable) return true;
  if (key !== ' ' && key !== 'Enter') return false;
  return !!target.closest(
    'button, a[href], summary, [role="button"], [role="link"], [role="checkbox"], [role="switch"], [role="slider"], [role="menuitem"], [role="tab"], [role="option"]',
  );
}

function numberParam(params, name) {
  if (!params.has(name)) return null;
  const x = Number(params.get(name));
  return Number.isFinite(x) ? x : null;
}

export async function startPlayer(id, params) {
  setState('loading');
  document.body.classList.add('page-player');
  const title = h('h1', { id: 'title' }, 'Reenactment');
  const subtitle = h('p', { id: 'subtitle', class: 'subtitle' }, id);
  const stageEl = h('div', { id: 'stage', class: 'stage' });
  const loadingEl = h('div', { id: 'loading', class: 'loading' }, 'Loading the reenactment…');
  const hud = h('div', { id: 'hud', class: 'hud' });
  const topbar = h(
    'header',
    { class: 'topbar' },
    h('a', { class: 'btn back', href: './', 'aria-label': 'Back to the library' }, '‹ Library'),
    h('div', { class: 'titles' }, title, subtitle),
  );
  stageEl.append(topbar, loadingEl);
  const overlay = document.getElementById('app');
  overlay.append(stageEl, hud);
  if (params.get('controls') === '0') document.body.classList.add('no-controls');

  const stage = new Stage(stageEl, {
    background: backgroundFromParams(params, '#1b1f24'),
    floor: params.get('floor') !== '0',
  });
  const player = {
    time: 0,
    playing: false,
    speed: 1,
    a: null,
    b: null,
    frame: 0,
    frames: 0,
    times: new Float64Array(0),
    // The timeline runs from the first frame's instant to the last's
    // (duration); the reenactment lasts frames / fps (length, as on its
    // library card).
    duration: 0,
    length: 0,
  };

  window.reenactStats = () => ({
    fps: stage.fps(),
    frame: player.frame,
    frames: player.frames,
    latency_ms: null,
  });
  window.reenactCamera = () => stage.cameraInfo();
  window.reenactPlayer = () => ({
    time: player.time,
    playing: player.playing,
    speed: player.speed,
    a: player.a,
    b: player.b,
    yaw_deg: stage.yawDeg,
    duration: player.duration,
    length_s: player.length,
    floor: stage.floor.visible,
    appearance: appearance ? appearance.stats() : null,
  });
  let appearance = null;

  // Metadata for the title (the glb's extras hold the rest).
  apiJson(`/api/v1/reenactments/${encodeURIComponent(id)}`)
    .then((r) => {
      title.textContent = cardTitle(r);
      const length = lengthSeconds(r.frames, r.fps) || Number(r.duration_s);
      subtitle.textContent = `${r.method} · ${formatSeconds(length)} s · ${r.frames} frames`;
      document.title = `${title.textContent} – Reenact`;
    })
    .catch(() => {});

  let gltf;
  let info;
  try {
    const buffer = await fetchGlb(id, (got, total) => {
      loadingEl.textContent = total
        ? `Loading the reenactment… ${Math.round((100 * got) / total)} %`
        : `Loading the reenactment… ${(got / 1e6).toFixed(1)} MB`;
    });
    ({ gltf, info } = await parseGlb(buffer));
  } catch (e) {
    loadingEl.hidden = true;
    showError(e, { retry: () => window.location.reload() });
    return;
  }
  loadingEl.hidden = true;
  clearError();

  const model = gltf.scene;
  const clip = gltf.animations[0] || null;
  player.times = frameTimes(clip, info);
  player.frames = player.times.length;
  player.duration = clip ? Math.max(clip.duration, player.times[player.times.length - 1] || 0) : 0;
  {
    const fps = info.fps || (player.duration > 0 && player.frames > 1 ? (player.frames - 1) / player.duration : 0);
    player.length = lengthSeconds(player.frames, fps) || player.duration;
  }
  const motion = analyseMotion(model, clip);
  stage.setModel(model, motion);
  stage.frame(motion);

  // The body's per-frame appearance, drawn once its video has loaded (the
  // static atlas until then, and where it cannot be).
  const appearanceNote = h('span', { id: 'appearance-note', class: 'note', role: 'status' }, '');
  appearance = new Appearance({
    id,
    model,
    frames: player.frames,
    fps: info.fps || (player.duration > 0 ? (player.frames - 1) / player.duration : 30),
    onChange: () => {
      appearanceNote.textContent = appearance.note;
      stage.invalidate();
    },
  });
  if (params.get('appearance') === '0') appearance.fallBack('per-frame appearance turned off (appearance=0)');
  else appearance.load();

  const mixer = new AnimationMixer(model);
  const action = clip ? mixer.clipAction(clip) : null;
  if (action) {
    action.setLoop(LoopRepeat, Infinity);
    action.play();
  }

  function apply() {
    player.time = Math.min(Math.max(player.time, 0), player.duration);
    if (action) {
      action.time = player.time;
      mixer.update(0);
    }
    player.frame = nearestFrame(player.times, player.time);
    stage.invalidate();
  }

  // ---- controls ----
  const playButton = h('button', { class: 'btn primary', id: 'play', type: 'button', 'aria-label': 'Play' }, '▶');
  const slider = h('input', {
    id: 'scrub',
    type: 'range',
    min: '0',
    max: String(player.duration || 0),
    step: 'any',
    value: '0',
    'aria-label': 'Time',
  });
  const timeLabel = h('output', { id: 'time', class: 'time' }, '0.00 s');
  const frameLabel = h('output', { id: 'frame', class: 'time' }, '');
  const speedSelect = h(
    'select',
    { id: 'speed', 'aria-label': 'Speed' },
    SPEEDS.map((s) => h('option', { value: String(s), selected: s === 1 }, `${s}×`)),
  );
  // The A-B loop's buttons say what they do on screen (a touch screen
  // shows no hover titles); the title adds when.
  const aButton = h('button', { class: 'btn', id: 'set-a', type: 'button', title: 'Start the loop at the current time' }, 'Loop start');
  const bButton = h('button', { class: 'btn', id: 'set-b', type: 'button', title: 'End the loop at the current time' }, 'Loop end');
  const clearAb = h('button', { class: 'btn', id: 'clear-ab', type: 'button', title: 'Play the whole reenactment again' }, 'Clear loop');
  const abLabel = h('output', { id: 'ab', class: 'time' }, '');
  const prevFrame = h('button', { class: 'btn', id: 'prev-frame', type: 'button', 'aria-label': 'Previous frame' }, '‹');
  const nextFrame = h('button', { class: 'btn', id: 'next-frame', type: 'button', 'aria-label': 'Next frame' }, '›');
  const mirrorButton = h('button', { class: 'btn toggle', id: 'mirror', type: 'button', 'aria-pressed': 'false' }, 'Mirror');
  const floorButton = h('button', { class: 'btn toggle', id: 'floor', type: 'button', 'aria-pressed': 'false' }, 'Floor');
  const yawSlider = h('input', {
    id: 'yaw',
    type: 'range',
    min: '-180',
    max: '180',
    step: '1',
    value: '0',
    'aria-label': 'Turn the teacher',
  });
  const yawLabel = h('output', { id: 'yaw-value', class: 'time' }, '0°');
  const faceMe = h('button', { class: 'btn', id: 'face-me', type: 'button' }, 'Face me');
  const resetView = h('button', { class: 'btn', id: 'reset-view', type: 'button' }, 'Reset view');
  const fullscreen = h('button', { class: 'btn', id: 'fullscreen', type: 'button' }, 'Fullscreen');
  const placeButton = h('button', { class: 'btn', id: 'ar-place', type: 'button', disabled: true }, 'Place (AR)');
  const arNote = h('span', { id: 'ar-note', class: 'note' }, '');

  const moreButton = h(
    'button',
    { class: 'btn more-toggle', id: 'more', type: 'button', 'aria-expanded': 'false', 'aria-controls': 'hud' },
    'More ▾',
  );
  moreButton.addEventListener('click', () => {
    const open = hud.classList.toggle('expanded');
    moreButton.setAttribute('aria-expanded', open ? 'true' : 'false');
    moreButton.textContent = open ? 'Less ▴' : 'More ▾';
  });
  hud.append(
    h('div', { class: 'row scrub-row' }, playButton, prevFrame, slider, nextFrame),
    h('div', { class: 'row readout' }, timeLabel, frameLabel, abLabel, appearanceNote, moreButton),
    h(
      'div',
      { class: 'row more' },
      h('label', { class: 'field' }, 'Speed ', speedSelect),
      aButton,
      bButton,
      clearAb,
      mirrorButton,
      floorButton,
    ),
    h(
      'div',
      { class: 'row more' },
      h('label', { class: 'field yaw' }, 'Turn ', yawSlider, yawLabel),
      faceMe,
      resetView,
      fullscreen,
      placeButton,
      arNote,
    ),
  );

  function setPlaying(on) {
    player.playing = !!on && player.duration > 0;
    playButton.textContent = player.playing ? '❚❚' : '▶';
    playButton.setAttribute('aria-label', player.playing ? 'Pause' : 'Play');
    setState(player.playing ? 'playing' : 'ready');
  }

  function seek(t) {
    player.time = t;
    apply();
    updateReadout();
  }

  function setSpeed(s) {
    const x = Math.min(2, Math.max(0.25, s));
    player.speed = x;
    if (!SPEEDS.includes(x)) speedSelect.append(h('option', { value: String(x) }, `${x}×`));
    speedSelect.value = String(x);
  }

  function setYaw(deg) {
    const d = stage.setYaw(deg);
    yawSlider.value = String(Math.round(d));
    yawLabel.textContent = `${Math.round(d)}°`;
  }

  function setMirror(on) {
    stage.setMirror(on);
    mirrorButton.setAttribute('aria-pressed', on ? 'true' : 'false');
  }

  function setFloor(on) {
    floorButton.setAttribute('aria-pressed', stage.setFloor(on) ? 'true' : 'false');
  }

  function updateAb() {
    const { a, b } = player;
    if (a === null && b === null) abLabel.textContent = '';
    else abLabel.textContent = `Loop ${a === null ? '…' : formatSeconds(a)}–${b === null ? '…' : formatSeconds(b)} s`;
    aButton.classList.toggle('on', a !== null);
    bButton.classList.toggle('on', b !== null);
  }

  let shownTime = -1;
  let shownFrame = -1;
  function updateReadout() {
    if (player.time !== shownTime) {
      shownTime = player.time;
      if (document.activeElement !== slider) slider.value = String(player.time);
      timeLabel.textContent = `${formatSeconds(player.time)} / ${formatSeconds(player.length)} s`;
    }
    if (player.frame !== shownFrame) {
      shownFrame = player.frame;
      frameLabel.textContent = `frame ${player.frame + 1} / ${player.frames}`;
    }
  }

  function stepFrame(delta) {
    setPlaying(false);
    const i = Math.min(player.frames - 1, Math.max(0, player.frame + delta));
    seek(player.times[i]);
  }

  playButton.addEventListener('click', () => {
    if (!player.playing && player.a === null && player.time >= player.duration) player.time = 0;
    setPlaying(!player.playing);
  });
  slider.addEventListener('input', () => seek(Number(slider.value)));
  prevFrame.addEventListener('click', () => stepFrame(-1));
  nextFrame.addEventListener('click', () => stepFrame(1));
  speedSelect.addEventListener('change', () => setSpeed(Number(speedSelect.value)));
  aButton.addEventListener('click', () => {
    player.a = player.time;
    if (player.b !== null && player.b <= player.a) player.b = null;
    updateAb();
  });
  bButton.addEventListener('click', () => {
    player.b = player.time;
    if (player.a !== null && player.a >= player.b) player.a = null;
    updateAb();
  });
  clearAb.addEventListener('click', () => {
    player.a = null;
    player.b = null;
    updateAb();
  });
  mirrorButton.addEventListener('click', () => setMirror(!stage.mirror));
  floorButton.addEventListener('click', () => setFloor(!stage.floor.visible));
  yawSlider.addEventListener('input', () => setYaw(Number(yawSlider.value)));
  faceMe.addEventListener('click', () => setYaw(stage.faceCameraYaw()));
  resetView.addEventListener('click', () => stage.resetView());
  if (!document.fullscreenEnabled) {
    fullscreen.disabled = true;
    fullscreen.title = 'This browser does not offer fullscreen here';
  }
  fullscreen.addEventListener('click', () => {
    if (document.fullscreenElement) document.exitFullscreen();
    else document.documentElement.requestFullscreen().catch(() => {});
  });
  document.addEventListener('fullscreenchange', () => {
    fullscreen.textContent = document.fullscreenElement ? 'Exit fullscreen' : 'Fullscreen';
  });
  // Shortcuts: Space plays and pauses, the arrows step a frame, M mirrors;
  // never with a modifier, nor on a control that answers the key itself.
  document.addEventListener('keydown', (e) => {
    if (e.defaultPrevented || e.ctrlKey || e.metaKey || e.altKey) return;
    if (controlTakesKey(e.target, e.key)) return;
    if (e.key === ' ') {
      if (e.repeat) return;
      e.preventDefault();
      playButton.click();
    } else if (e.key === 'ArrowLeft') stepFrame(-1);
    else if (e.key === 'ArrowRight') stepFrame(1);
    else if (e.key === 'm') mirrorButton.click();
  });

  // ---- the clock ----
  stage.onFrame = (dt) => {
    if (player.playing) {
      let t = player.time + dt * player.speed;
      const { a, b } = player;
      const start = a !== null ? a : 0;
      const end = b !== null ? b : player.duration;
      if (end > start) {
        if (t > end) t = start + ((t - end) % (end - start));
        if (t < start) t = start;
      } else if (t > player.duration) {
        t = player.duration > 0 ? t % player.duration : 0;
      }
      player.time = t;
      apply();
    }
    appearance.sync(player.time, player.frame, player.playing, player.speed);
    updateReadout();
  };

  // ---- deep link ----
  const t0 = numberParam(params, 't');
  const yaw0 = numberParam(params, 'yaw');
  const speed0 = numberParam(params, 'speed');
  const a0 = numberParam(params, 'a');
  const b0 = numberParam(params, 'b');
  if (speed0 !== null) setSpeed(speed0);
  if (yaw0 !== null) setYaw(yaw0);
  setMirror(params.get('mirror') === '1');
  setFloor(params.get('floor') !== '0');
  if (a0 !== null) player.a = Math.max(0, a0);
  if (b0 !== null && (player.a === null || b0 > player.a)) player.b = Math.min(player.duration, b0);
  updateAb();
  seek(t0 !== null ? t0 : player.a !== null ? player.a : 0);
  setPlaying(params.get('paused') !== '1');
  setStatus('');

  setupAr({
    stage,
    button: placeButton,
    note: arNote,
    overlay,
    motion,
    onPlaced: () => setYaw(stage.faceCameraYaw()),
    onSessionChange: (active) => {
      document.body.classList.toggle('ar', active);
      if (!active) stage.resize();
    },
  });
}
