// The player's controls at work: each changes the playback state, poses
// the model and shows the result; the clock moves the state on each frame.

import { setupAr } from '../ar.js';
import { bindViewControls } from '../view-controls.js';
import { bindShortcuts } from './keys.js';
import { PlayerReadout } from './readout.js';

// The actions on the player: `playback` (lib/playback.js), `stage`, `pose`
// (time => the model posed then) and `hud` (createPlayerHud's controls).
export function createPlayerActions({ playback, stage, pose, hud }) {
  const readout = new PlayerReadout(hud);
  const show = () => {
    pose(playback.time);
    stage.invalidate();
  };
  const actions = {
    readout,
    show,
    ...bindViewControls(stage, hud, { fullscreenHints: true }),
    seek(t) {
      playback.seek(t);
      show();
      readout.update(playback);
    },
    setPlaying(on) {
      readout.showPlaying(playback.setPlaying(on));
    },
    togglePlaying() {
      readout.showPlaying(playback.togglePlaying());
    },
    setSpeed(s) {
      readout.showSpeed(playback.setSpeed(s));
    },
    stepFrame(delta) {
      actions.setPlaying(false);
      actions.seek(playback.frameTimeAfter(delta));
    },
    changeLoop(change) {
      change.call(playback);
      readout.showLoop(playback);
    },
  };
  return actions;
}

// Wires the HUD's transport, speed and loop controls and the keyboard to
// `actions` (createPlayerActions').
export function bindPlayerControls(hud, actions, playback) {
  hud.playButton.addEventListener('click', () => actions.togglePlaying());
  hud.slider.addEventListener('input', () => actions.seek(Number(hud.slider.value)));
  hud.prevFrame.addEventListener('click', () => actions.stepFrame(-1));
  hud.nextFrame.addEventListener('click', () => actions.stepFrame(1));
  hud.speedSelect.addEventListener('change', () => actions.setSpeed(Number(hud.speedSelect.value)));
  hud.aButton.addEventListener('click', () => actions.changeLoop(playback.markLoopStart));
  hud.bButton.addEventListener('click', () => actions.changeLoop(playback.markLoopEnd));
  hud.clearAb.addEventListener('click', () => actions.changeLoop(playback.clearLoop));
  bindShortcuts({
    play: (e) => {
      if (e.repeat) return;
      e.preventDefault();
      hud.playButton.click();
    },
    previous: () => actions.stepFrame(-1),
    next: () => actions.stepFrame(1),
    mirror: () => hud.mirrorButton.click(),
  });
}

// The clock: on each frame the playback moves on (while playing), the
// appearance video follows and the readouts show it.
export function runClock({ stage, playback, actions, appearance }) {
  stage.onFrame = (dt) => {
    if (playback.advance(dt)) actions.show();
    appearance.sync(playback.time, playback.frame, playback.playing, playback.speed);
    actions.readout.update(playback);
  };
}

// The deep link's state (lib/params.js playerParams'): speed, turn,
// mirror, floor, loop, time, paused.
export function applyDeepLink(link, playback, actions) {
  if (link.speed !== null) actions.setSpeed(link.speed);
  if (link.yaw !== null) actions.setYaw(link.yaw);
  actions.setMirror(link.mirror);
  actions.setFloor(link.floor);
  playback.setLoopFromLink(link.a, link.b);
  actions.readout.showLoop(playback);
  actions.seek(playback.startTime(link.t));
  actions.setPlaying(!link.paused);
}

// AR placement on the HUD's button; the teacher turns to face whoever
// placed it.
export function offerAr({ stage, hud, overlay, motion, actions }) {
  setupAr({
    stage,
    button: hud.placeButton,
    note: hud.arNote,
    overlay,
    motion,
    onPlaced: () => actions.setYaw(stage.faceCameraYaw()),
    onSessionChange: (active) => {
      document.body.classList.toggle('ar', active);
      if (!active) stage.resize();
    },
  });
}
