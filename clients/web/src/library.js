// The library (/): the server's reenactments, newest first, each with a
// still drawn here when its card scrolls into view, and the live jobs one
// can watch. Refreshes itself; when the server is away it says so and keeps
// trying.

import { ApiError, apiJson, apiJsonAllPages, describeError } from './api.js';
import { still } from './stills.js';
import { backgroundFromParams } from './player.js';
import {
  cardTitle,
  clearError,
  formatDate,
  formatSeconds,
  h,
  lengthSeconds,
  setState,
  setStatus,
  showError,
  uploadedFileName,
} from './ui.js';

const REFRESH_MS = 5000;
const RETRY_MS = 3000;

// What to do when there is nothing to show yet: the commands a coach's
// technician runs (README.md, "Capturing" and "Reenactments").
function emptyHelp() {
  const code = (text) => h('code', {}, text);
  return [
    h('strong', {}, 'No reenactments yet. '),
    'A reenactment is made from a recorded take in two steps:',
    h(
      'ol',
      {},
      h(
        'li',
        {},
        'Record a take with the sensors (',
        code('reenactd --server HOST:50051 --once'),
        ') or upload a recording made elsewhere (',
        code('reenact takes upload FILE.mcap --server HOST:50051'),
        ').',
      ),
      h(
        'li',
        {},
        'Run a job on it: ',
        code('reenact jobs submit --server HOST:50051 --take TAKE_ID --method body --wait'),
        ' (',
        code('reenact takes list'),
        ' shows the take ids).',
      ),
    ),
    'It appears here by itself a few seconds after the job ends. ',
    'The README\'s "Capturing" and "Reenactments" sections say more.',
  ];
}

export function startLibrary(params) {
  document.body.classList.add('page-library');
  const bg = backgroundFromParams(params, '');
  if (bg) document.body.style.background = bg;
  setState('loading');

  const liveList = h('ul', { id: 'live-list', class: 'live-list' });
  const liveNote = h('p', { id: 'live-note', class: 'note' }, '');
  const grid = h('ul', { id: 'reenactments', class: 'grid' });
  const emptyNote = h('div', { id: 'empty-note', class: 'note empty-note', hidden: true }, emptyHelp());
  const serverLine = h('p', { id: 'server-line', class: 'note' }, '');
  document.getElementById('app').append(
    h(
      'div',
      { class: 'library' },
      h('header', { class: 'library-head' }, h('h1', {}, 'Reenact'), serverLine),
      h('section', { id: 'live', 'aria-labelledby': 'live-title' }, h('h2', { id: 'live-title' }, 'Live'), liveNote, liveList),
      h(
        'section',
        { id: 'library', 'aria-labelledby': 'library-title' },
        h('h2', { id: 'library-title' }, 'Reenactments'),
        emptyNote,
        grid,
      ),
    ),
  );

  const observer = new IntersectionObserver(
    (entries) => {
      for (const entry of entries) {
        if (!entry.isIntersecting) continue;
        observer.unobserve(entry.target);
        loadStill(entry.target);
      }
    },
    { rootMargin: '200px' },
  );

  function loadStill(card) {
    const id = card.dataset.id;
    const frame = card.querySelector('.still');
    frame.classList.add('busy');
    still(id)
      .then((url) => {
        frame.replaceChildren(h('img', { src: url, alt: '', draggable: false }));
        frame.classList.remove('busy');
        frame.classList.add('done');
      })
      .catch((e) => {
        frame.classList.remove('busy');
        frame.classList.add('failed');
        frame.replaceChildren(h('span', { class: 'placeholder' }, 'No preview'));
        frame.title = describeError(e);
      });
  }

  const cards = new Map(); // id -> card element

  function card(r) {
    const created = formatDate(r.created_unix_ns);
    const file = uploadedFileName(r.take_name);
    const length = lengthSeconds(r.frames, r.fps) || Number(r.duration_s);
    return h(
      'li',
      { class: 'card-item' },
      h(
        'a',
        { class: 'card', href: `?reenactment=${encodeURIComponent(r.id)}`, dataset: { id: r.id } },
        h('div', { class: 'still' }, h('span', { class: 'placeholder' }, r.kind === 'rigid' ? 'Rigid parts' : 'Body')),
        h(
          'div',
          { class: 'card-body' },
          h('h3', { class: 'card-title' }, cardTitle(r)),
          created ? h('p', { class: 'card-when' }, created) : null,
          file ? h('p', { class: 'card-file', title: 'The file this take was uploaded from' }, `from ${file}`) : null,
          h(
            'dl',
            { class: 'facts' },
            h('dt', {}, 'Method'),
            h('dd', { class: 'method' }, r.method),
            h('dt', {}, 'Length'),
            h('dd', { class: 'length' }, `${formatSeconds(length)} s`),
            h('dt', {}, 'Frames'),
            h('dd', { class: 'frames' }, String(r.frames)),
          ),
        ),
      ),
    );
  }

  function showReenactments(list) {
    const ids = list.map((r) => r.id);
    const same = ids.length === cards.size && ids.every((id) => cards.has(id));
    emptyNote.hidden = list.length > 0;
    if (same) return;
    const items = [];
    const next = new Map();
    for (const r of list) {
      let item = cards.get(r.id);
      if (!item) {
        item = card(r);
        observer.observe(item.querySelector('.card'));
      }
      next.set(r.id, item);
      items.push(item);
    }
    for (const [id, item] of cards) if (!next.has(id)) observer.unobserve(item.querySelector('.card'));
    cards.clear();
    for (const [id, item] of next) cards.set(id, item);
    grid.replaceChildren(...items);
  }

  function showLive(jobs) {
    const running = jobs.filter((j) => j.live && (j.state === 'running' || j.state === 'queued'));
    liveNote.textContent = running.length ? '' : 'No live jobs right now.';
    liveList.replaceChildren(
      ...running.map((j) =>
        h(
          'li',
          { class: 'live-item', dataset: { id: j.id } },
          h(
            'div',
            { class: 'live-text' },
            h('strong', {}, j.take_id),
            h('span', { class: 'note' }, ` ${j.method} · ${j.state}${j.stage ? ` · ${j.stage}` : ''} · started ${formatDate(j.created_unix_ns)}`),
          ),
          h('a', { class: 'btn primary watch', href: `?job=${encodeURIComponent(j.id)}` }, 'Watch'),
        ),
      ),
    );
  }

  let timer = 0;
  let failures = 0;

  async function refresh() {
    clearTimeout(timer);
    try {
      const [info, list] = await Promise.all([
        apiJson('/api/v1/info').catch((e) => {
          if (e instanceof ApiError && e.status !== 0) return null;
          throw e;
        }),
        apiJsonAllPages('/api/v1/reenactments', { page_size: 50 }),
      ]);
      if (info) serverLine.textContent = `${info.name} ${info.version}${info.tls ? ' · TLS' : ''}${info.auth ? ' · tokens' : ''}`;
      showReenactments(list);
      try {
        showLive(await apiJson('/api/v1/jobs?live=1'));
      } catch (e) {
        if (e instanceof ApiError && e.status === 403) liveNote.textContent = "This token's role may not list jobs.";
        else if (e instanceof ApiError && e.status === 404) liveNote.textContent = 'This server lists no jobs.';
        else throw e;
      }
      if (failures > 0) setStatus('The server is back.');
      failures = 0;
      clearError();
      setState('ready');
      timer = setTimeout(refresh, REFRESH_MS);
    } catch (e) {
      ++failures;
      const fatal = e instanceof ApiError && (e.status === 401 || e.status === 403);
      showError(e, { retry: refresh, retryLabel: 'Retry now' });
      if (!fatal) {
        setStatus(`Retrying every ${RETRY_MS / 1000} s (attempt ${failures}).`);
        timer = setTimeout(refresh, RETRY_MS);
      }
    }
  }

  window.reenactStats = () => ({ fps: 0, frame: 0, frames: 0, latency_ms: null });
  refresh();
}
