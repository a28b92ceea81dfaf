// The page's keyboard shortcuts, on the document, leaving alone the keys a
// focused control answers itself.

import { CONTROL_KEYS, KEY_CONTROLS, shortcutOf } from '../lib/keys.js';

// Whether the focused `target` answers `key` itself: Space and Enter press
// a button or follow a link, any key types into a field, moves a slider or
// opens a list. The page's shortcuts leave them alone there.
export function controlTakesKey(target, key) {
  if (!(target instanceof Element)) return false;
  if (
    target instanceof HTMLInputElement ||
    target instanceof HTMLSelectElement ||
    target instanceof HTMLTextAreaElement
  ) {
    return true;
  }
  if (target.isContentEditable) return true;
  if (!CONTROL_KEYS.has(key)) return false;
  return !!target.closest(KEY_CONTROLS);
}

// Calls actions[name](event) for each shortcut (lib/keys.js's names) that
// no focused control takes.
export function bindShortcuts(actions) {
  document.addEventListener('keydown', (e) => {
    const action = shortcutOf(e);
    if (!action || controlTakesKey(e.target, e.key)) return;
    actions[action](e);
  });
}
