// The view's controls, shared by the player and the live preview: the
// mirror image, the floor grid, the teacher's turn ("Face me"), the view's
// reset and fullscreen.

import { formatDegrees } from './lib/format.js';
import { h } from './ui.js';

// The controls' elements; `turnLabel` names the turn slider for screen
// readers.
export function createViewControls(turnLabel) {
  return {
    mirrorButton: h('button', { class: 'btn toggle', id: 'mirror', type: 'button', 'aria-pressed': 'false' }, 'Mirror'),
    floorButton: h('button', { class: 'btn toggle', id: 'floor', type: 'button', 'aria-pressed': 'false' }, 'Floor'),
    yawSlider: h('input', {
      id: 'yaw',
      type: 'range',
      min: '-180',
      max: '180',
      step: '1',
      value: '0',
      'aria-label': turnLabel,
    }),
    yawLabel: h('output', { id: 'yaw-value', class: 'time' }, '0°'),
    faceMe: h('button', { class: 'btn', id: 'face-me', type: 'button' }, 'Face me'),
    resetView: h('button', { class: 'btn', id: 'reset-view', type: 'button' }, 'Reset view'),
    fullscreen: h('button', { class: 'btn', id: 'fullscreen', type: 'button' }, 'Fullscreen'),
  };
}

// Wires `controls` (createViewControls') to `stage`. With `fullscreenHints`
// the fullscreen button says why it is off and names its state ("Exit
// fullscreen"). Returns the setters {setYaw, setMirror, setFloor}.
export function bindViewControls(stage, controls, { fullscreenHints = false } = {}) {
  const { mirrorButton, floorButton, yawSlider, yawLabel, faceMe, resetView } = controls;
  const setYaw = (deg) => {
    const d = stage.setYaw(deg);
    yawSlider.value = String(Math.round(d));
    yawLabel.textContent = formatDegrees(d);
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
  bindFullscreen(controls.fullscreen, fullscreenHints);
  return { setYaw, setMirror, setFloor };
}

function bindFullscreen(button, hints) {
  if (!document.fullscreenEnabled) {
    button.disabled = true;
    if (hints) button.title = 'This browser does not offer fullscreen here';
  }
  button.addEventListener('click', () => {
    if (document.fullscreenElement) document.exitFullscreen();
    else document.documentElement.requestFullscreen().catch(() => {});
  });
  if (!hints) return;
  document.addEventListener('fullscreenchange', () => {
    button.textContent = document.fullscreenElement ? 'Exit fullscreen' : 'Fullscreen';
  });
}
