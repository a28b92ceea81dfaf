// Loading the player's reenactment: its model.glb with the progress on the
// loading line, and the animation that poses the model at a time.

import { AnimationMixer, LoopRepeat } from 'three';
import { fetchGlb } from '../api.js';
import { loadingText } from '../lib/glb.js';
import { parseGlb } from '../model.js';
import { clearError, showError } from '../ui.js';

// The parsed model {gltf, info}, or null after showing why it could not be
// had (with a retry).
export async function loadReenactment(id, loadingEl) {
  let loaded;
  try {
    const buffer = await fetchGlb(id, (got, total) => {
      loadingEl.textContent = loadingText(got, total);
    });
    loaded = await parseGlb(buffer);
  } catch (e) {
    loadingEl.hidden = true;
    showError(e, { retry: () => window.location.reload() });
    return null;
  }
  loadingEl.hidden = true;
  clearError();
  return loaded;
}

// A function that poses `model` at a time (seconds) on `clip` (none: it
// does nothing).
export function createPoser(model, clip) {
  const mixer = new AnimationMixer(model);
  const action = clip ? mixer.clipAction(clip) : null;
  if (!action) return () => {};
  action.setLoop(LoopRepeat, Infinity);
  action.play();
  return (time) => {
    action.time = time;
    mixer.update(0);
  };
}
