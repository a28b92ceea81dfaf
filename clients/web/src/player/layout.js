// The player's page: the stage with its top bar (back link, title) and
// loading line, the HUD under it, and the title from the server's
// metadata.

import { apiJson } from '../api.js';
import { cardTitle, reenactmentSummary } from '../lib/format.js';
import { reenactmentLength } from '../lib/timeline.js';
import { h } from '../ui.js';

// Builds the page in #app; `controls`: whether the HUD shows (&controls=0
// hides it). {title, subtitle, stageEl, loadingEl, hud, overlay}.
export function createPlayerLayout(id, controls) {
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
  if (!controls) document.body.classList.add('no-controls');
  return { title, subtitle, stageEl, loadingEl, hud, overlay };
}

// Titles the page from the reenactment's metadata (the glb's extras hold
// the rest); without it the id stays.
export function showTitle(id, { title, subtitle }) {
  apiJson(`/api/v1/reenactments/${encodeURIComponent(id)}`)
    .then((r) => {
      title.textContent = cardTitle(r);
      subtitle.textContent = reenactmentSummary(r, reenactmentLength(r));
      document.title = `${title.textContent} – Reenact`;
    })
    .catch(() => {});
}
