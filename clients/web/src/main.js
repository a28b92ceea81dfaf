// Reenact in the browser: the library (/), the player (/?reenactment=ID)
// and the live preview (/?job=JOBID).

import { adoptTokenFromFragment } from './api.js';
import { startLibrary } from './library.js';
import { startLive } from './live.js';
import { startPlayer } from './player.js';
import { showError } from './ui.js';

function main() {
  adoptTokenFromFragment();
  const params = new URLSearchParams(window.location.search);
  const reenactment = params.get('reenactment');
  const job = params.get('job');
  if (reenactment) return startPlayer(reenactment, params);
  if (job) return startLive(job, params);
  return startLibrary(params);
}

window.addEventListener('unhandledrejection', (e) => {
  if (document.body.dataset.state === 'loading') showError(e.reason || 'Something went wrong.');
});

try {
  Promise.resolve(main()).catch((e) => showError(e));
} catch (e) {
  showError(e);
}
