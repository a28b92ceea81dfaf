// The library's page: its sections, the help for an empty library, a
// reenactment's card and a live job's line.

import { cardTitle, formatDate, formatSeconds, liveJobLine, uploadedFileName } from '../lib/format.js';
import { reenactmentLength } from '../lib/timeline.js';
import { h } from '../ui.js';

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

// Builds the page in #app. {liveList, liveNote, grid, emptyNote, serverLine}.
export function createLibraryLayout() {
  const c = {
    liveList: h('ul', { id: 'live-list', class: 'live-list' }),
    liveNote: h('p', { id: 'live-note', class: 'note' }, ''),
    grid: h('ul', { id: 'reenactments', class: 'grid' }),
    emptyNote: h('div', { id: 'empty-note', class: 'note empty-note', hidden: true }, emptyHelp()),
    serverLine: h('p', { id: 'server-line', class: 'note' }, ''),
  };
  document
    .getElementById('app')
    .append(
      h(
        'div',
        { class: 'library' },
        h('header', { class: 'library-head' }, h('h1', {}, 'Reenact'), c.serverLine),
        h(
          'section',
          { id: 'live', 'aria-labelledby': 'live-title' },
          h('h2', { id: 'live-title' }, 'Live'),
          c.liveNote,
          c.liveList,
        ),
        h(
          'section',
          { id: 'library', 'aria-labelledby': 'library-title' },
          h('h2', { id: 'library-title' }, 'Reenactments'),
          c.emptyNote,
          c.grid,
        ),
      ),
    );
  return c;
}

// The facts under a card's title: method, length (frames / fps), frames.
function facts(r) {
  return h(
    'dl',
    { class: 'facts' },
    h('dt', {}, 'Method'),
    h('dd', { class: 'method' }, r.method),
    h('dt', {}, 'Length'),
    h('dd', { class: 'length' }, `${formatSeconds(reenactmentLength(r))} s`),
    h('dt', {}, 'Frames'),
    h('dd', { class: 'frames' }, String(r.frames)),
  );
}

// A reenactment's card: a link to the player with a still (drawn later),
// its title, date, the file its take came from and its facts.
export function reenactmentCard(r) {
  const created = formatDate(r.created_unix_ns);
  const file = uploadedFileName(r.take_name);
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
        facts(r),
      ),
    ),
  );
}

// A live job's line with its Watch link.
export function liveJobItem(j) {
  return h(
    'li',
    { class: 'live-item', dataset: { id: j.id } },
    h(
      'div',
      { class: 'live-text' },
      h('strong', {}, j.take_id),
      h('span', { class: 'note' }, liveJobLine(j, formatDate(j.created_unix_ns))),
    ),
    h('a', { class: 'btn primary watch', href: `?job=${encodeURIComponent(j.id)}` }, 'Watch'),
  );
}
