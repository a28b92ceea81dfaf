// The library's grid of reenactment cards: kept across refreshes (a card
// is made once), each still drawn when its card scrolls into view.

import { describeError } from '../api.js';
import { sameIds } from '../lib/listing.js';
import { still } from '../stills.js';
import { h } from '../ui.js';
import { reenactmentCard } from './view.js';

// Draws the still of `card` (a .card link with data-id) into its .still.
function loadStill(card) {
  const frame = card.querySelector('.still');
  frame.classList.add('busy');
  still(card.dataset.id)
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

export class CardGrid {
  // `grid`: the list the cards go in; `emptyNote`: shown while there are
  // none.
  constructor(grid, emptyNote) {
    this.grid = grid;
    this.emptyNote = emptyNote;
    this.cards = new Map(); // id -> card element
    this.observer = new IntersectionObserver(
      (entries) => {
        for (const entry of entries) {
          if (!entry.isIntersecting) continue;
          this.observer.unobserve(entry.target);
          loadStill(entry.target);
        }
      },
      { rootMargin: '200px' },
    );
  }

  // Shows `list` (the server's reenactments, in its order); touches the
  // page only when the set of ids changed.
  show(list) {
    this.emptyNote.hidden = list.length > 0;
    if (sameIds(list, this.cards)) return;
    const items = [];
    const next = new Map();
    for (const r of list) {
      let item = this.cards.get(r.id);
      if (!item) {
        item = reenactmentCard(r);
        this.observer.observe(item.querySelector('.card'));
      }
      next.set(r.id, item);
      items.push(item);
    }
    for (const [id, item] of this.cards) if (!next.has(id)) this.observer.unobserve(item.querySelector('.card'));
    this.cards = next;
    this.grid.replaceChildren(...items);
  }
}
