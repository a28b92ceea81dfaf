// The player's state on screen: the play button, the time slider and
// readouts, the loop's readout and buttons, the speed list. Writes only
// what changed.

import { frameReadout, loopReadout, timeReadout } from '../lib/format.js';
import { SPEEDS } from '../lib/timeline.js';
import { h, setState } from '../ui.js';

export class PlayerReadout {
  // `hud`: createPlayerHud's controls.
  constructor(hud) {
    this.hud = hud;
    this.shownTime = -1;
    this.shownFrame = -1;
  }

  // The time and frame of `playback` (the slider stays under a finger).
  update(playback) {
    const { slider, timeLabel, frameLabel } = this.hud;
    if (playback.time !== this.shownTime) {
      this.shownTime = playback.time;
      if (document.activeElement !== slider) slider.value = String(playback.time);
      timeLabel.textContent = timeReadout(playback.time, playback.length);
    }
    if (playback.frame !== this.shownFrame) {
      this.shownFrame = playback.frame;
      frameLabel.textContent = frameReadout(playback.frame, playback.frames);
    }
  }

  // Playing or paused: the play button and the page's state.
  showPlaying(playing) {
    const { playButton } = this.hud;
    playButton.textContent = playing ? '❚❚' : '▶';
    playButton.setAttribute('aria-label', playing ? 'Pause' : 'Play');
    setState(playing ? 'playing' : 'ready');
  }

  // The A-B loop: its readout, and which ends are set.
  showLoop({ a, b }) {
    const { abLabel, aButton, bButton } = this.hud;
    abLabel.textContent = loopReadout(a, b);
    aButton.classList.toggle('on', a !== null);
    bButton.classList.toggle('on', b !== null);
  }

  // The speed in the list (one the list lacks is added).
  showSpeed(speed) {
    const { speedSelect } = this.hud;
    if (!SPEEDS.includes(speed)) speedSelect.append(h('option', { value: String(speed) }, `${speed}×`));
    speedSelect.value = String(speed);
  }
}
