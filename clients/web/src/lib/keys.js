// The player's keyboard shortcuts: Space plays and pauses, the arrows step
// a frame, M mirrors; never with a modifier.

const SHORTCUTS = new Map([
  [' ', 'play'],
  ['ArrowLeft', 'previous'],
  ['ArrowRight', 'next'],
  ['m', 'mirror'],
]);

// The action a key event ({key, ctrlKey, metaKey, altKey, defaultPrevented})
// asks for: 'play', 'previous', 'next', 'mirror', or '' for none.
export function shortcutOf(event) {
  if (event.defaultPrevented || event.ctrlKey || event.metaKey || event.altKey) return '';
  return SHORTCUTS.get(event.key) || '';
}

// Keys a focused button, link or other control answers itself (Space and
// Enter press, follow or open it), and the selector of such controls.
export const CONTROL_KEYS = new Set([' ', 'Enter']);
export const KEY_CONTROLS = [
  'button',
  'a[href]',
  'summary',
  '[role="button"]',
  '[role="link"]',
  '[role="checkbox"]',
  '[role="switch"]',
  '[role="slider"]',
  '[role="menuitem"]',
  '[role="tab"]',
  '[role="option"]',
].join(', ');
