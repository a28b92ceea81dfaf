// The live preview's page: the stage with its top bar, the HUD with the
// latency, frame and frame-rate readouts, the view's controls and the line
// that links the finished reenactment.

import { h } from '../ui.js';
import { createViewControls } from '../view-controls.js';

// The readouts: capture-to-screen latency, frames, frame rate.
function createReadouts() {
  return {
    latencyLabel: h('output', { id: 'latency', class: 'big-figure' }, '– ms'),
    framesLabel: h('output', { id: 'live-frames', class: 'time' }, ''),
    fpsLabel: h('output', { id: 'live-fps', class: 'time' }, ''),
  };
}

// Builds the page in #app; `controls`: whether the HUD shows (&controls=0
// hides it). Returns every element the page writes to, by name, with the
// stage's element (stageEl).
export function createLiveLayout(jobId, controls) {
  document.body.classList.add('page-live');
  const stageEl = h('div', { id: 'stage', class: 'stage' });
  const c = {
    title: h('h1', { id: 'title' }, 'Live'),
    subtitle: h('p', { id: 'subtitle', class: 'subtitle' }, jobId),
    ...createReadouts(),
    ...createViewControls('Turn'),
    afterwards: h('p', { id: 'afterwards', class: 'note', hidden: true }),
  };
  const hud = h(
    'div',
    { id: 'hud', class: 'hud' },
    h(
      'div',
      { class: 'row readout' },
      h('span', { class: 'label' }, 'Capture → screen'),
      c.latencyLabel,
      c.framesLabel,
      c.fpsLabel,
    ),
    h(
      'div',
      { class: 'row' },
      c.mirrorButton,
      c.floorButton,
      h('label', { class: 'field yaw' }, 'Turn ', c.yawSlider, c.yawLabel),
      c.faceMe,
      c.resetView,
      c.fullscreen,
    ),
    c.afterwards,
  );
  stageEl.append(
    h(
      'header',
      { class: 'topbar' },
      h('a', { class: 'btn back', href: './', 'aria-label': 'Back to the library' }, '‹ Library'),
      h('div', { class: 'titles' }, c.title, c.subtitle),
    ),
  );
  document.getElementById('app').append(stageEl, hud);
  if (!controls) document.body.classList.add('no-controls');
  return { ...c, stageEl };
}
