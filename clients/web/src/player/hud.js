// The player's controls in the HUD: the transport (play, frame steps, the
// time slider), the readouts, and under "More" the speed, the A-B loop, the
// view's controls and AR placement.

import { SPEEDS } from '../lib/timeline.js';
import { h } from '../ui.js';
import { createViewControls } from '../view-controls.js';

// The transport and its readouts over a timeline `duration` seconds long.
function createTransport(duration) {
  return {
    playButton: h('button', { class: 'btn primary', id: 'play', type: 'button', 'aria-label': 'Play' }, '▶'),
    slider: h('input', {
      id: 'scrub',
      type: 'range',
      min: '0',
      max: String(duration || 0),
      step: 'any',
      value: '0',
      'aria-label': 'Time',
    }),
    timeLabel: h('output', { id: 'time', class: 'time' }, '0.00 s'),
    frameLabel: h('output', { id: 'frame', class: 'time' }, ''),
    prevFrame: h('button', { class: 'btn', id: 'prev-frame', type: 'button', 'aria-label': 'Previous frame' }, '‹'),
    nextFrame: h('button', { class: 'btn', id: 'next-frame', type: 'button', 'aria-label': 'Next frame' }, '›'),
  };
}

// The speed list and the A-B loop's buttons. They say what they do on
// screen (a touch screen shows no hover titles); the title adds when.
function createLoopControls() {
  const button = (id, title, text) => h('button', { class: 'btn', id, type: 'button', title }, text);
  return {
    speedSelect: h(
      'select',
      { id: 'speed', 'aria-label': 'Speed' },
      SPEEDS.map((s) => h('option', { value: String(s), selected: s === 1 }, `${s}×`)),
    ),
    aButton: button('set-a', 'Start the loop at the current time', 'Loop start'),
    bButton: button('set-b', 'End the loop at the current time', 'Loop end'),
    clearAb: button('clear-ab', 'Play the whole reenactment again', 'Clear loop'),
    abLabel: h('output', { id: 'ab', class: 'time' }, ''),
  };
}

// "More ▾": shows and hides the HUD's further rows.
function createMoreButton(hud) {
  const more = h(
    'button',
    { class: 'btn more-toggle', id: 'more', type: 'button', 'aria-expanded': 'false', 'aria-controls': 'hud' },
    'More ▾',
  );
  more.addEventListener('click', () => {
    const open = hud.classList.toggle('expanded');
    more.setAttribute('aria-expanded', open ? 'true' : 'false');
    more.textContent = open ? 'Less ▴' : 'More ▾';
  });
  return more;
}

// Builds the controls into `hud`, with `appearanceNote` among the
// readouts. Returns every control by name.
export function createPlayerHud(hud, duration, appearanceNote) {
  const c = {
    ...createTransport(duration),
    ...createLoopControls(),
    ...createViewControls('Turn the teacher'),
    placeButton: h('button', { class: 'btn', id: 'ar-place', type: 'button', disabled: true }, 'Place (AR)'),
    arNote: h('span', { id: 'ar-note', class: 'note' }, ''),
  };
  hud.append(
    h('div', { class: 'row scrub-row' }, c.playButton, c.prevFrame, c.slider, c.nextFrame),
    h('div', { class: 'row readout' }, c.timeLabel, c.frameLabel, c.abLabel, appearanceNote, createMoreButton(hud)),
    h(
      'div',
      { class: 'row more' },
      h('label', { class: 'field' }, 'Speed ', c.speedSelect),
      c.aButton,
      c.bButton,
      c.clearAb,
      c.mirrorButton,
      c.floorButton,
    ),
    h(
      'div',
      { class: 'row more' },
      h('label', { class: 'field yaw' }, 'Turn ', c.yawSlider, c.yawLabel),
      c.faceMe,
      c.resetView,
      c.fullscreen,
      c.placeButton,
      c.arNote,
    ),
  );
  return c;
}
