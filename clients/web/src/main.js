// Reenact in the browser: the library (/), the player (/?reenactment=ID)
// and the live preview (/?job=JOBID).

import { adoptTokenFromFragment } from './api.js';
import { routeOf } from './lib/params.js';
import { startLibrary } from './library.js';
import { startLive } from './live.js';
import { startPlayer } from './player.js';
import { showError } from './ui.js';

// Each page by the name lib/params.js's routeOf gives it.
const PAGES = {
  library: (id, params) => startLibrary(params),
  player: (id, params) => startPlayer(id, params),
  live: (id, params) => startLive(id, params),
};

function main() {
  adoptTokenFromFragment();
  const params = new URLSearchParams(window.location.search);
  const { page, id } = routeOf(params);
  return PAGES[page](id, params);
}

window.addEventListener('unhandledrejection', (e) => {
  if (document.body.dataset.state === 'loading') showError(e.reason || 'Something went wrong.');
});

try {
  Promise.resolve(main()).catch((e) => showError(e));
} catch (e) {
  showError(e);
}
