// Small DOM helpers and the page-wide state and error display.

import { ApiError, describeError, setToken } from './api.js';

// h('button', {class: 'x', onclick: f}, 'text', child, ...)
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith('on') && typeof value === 'function') {
      el.addEventListener(key.slice(2), value);
    } else if (key === 'class') {
      el.className = value;
    } else if (key === 'dataset') {
      Object.assign(el.dataset, value);
    } else if (key in el && typeof value !== 'string') {
      el[key] = value;
    } else {
      el.setAttribute(key, value === true ? '' : value);
    }
  }
  for (const child of children.flat()) {
    if (child === undefined || child === null || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

// document.body.dataset.state: loading | ready | playing | error.
export function setState(state) {
  if (document.body.dataset.state !== state) document.body.dataset.state = state;
}

export function getState() {
  return document.body.dataset.state || '';
}

const errorBox = () => document.getElementById('error');

// Shows `error` (an Error/ApiError or a sentence) in #error and sets the
// state to error. `retry`, when given, adds a button. A 401 adds a token
// prompt.
export function showError(error, { retry, retryLabel = 'Try again', keepState = false } = {}) {
  const box = errorBox();
  const text = typeof error === 'string' ? error : describeError(error);
  box.replaceChildren(h('p', { id: 'error-message' }, text));
  if (error instanceof ApiError && error.status === 401) {
    box.append(tokenPrompt());
  }
  if (retry) {
    box.append(h('button', { class: 'btn', type: 'button', onclick: retry }, retryLabel));
  }
  box.hidden = false;
  if (!keepState) setState('error');
}

export function clearError() {
  const box = errorBox();
  box.hidden = true;
  box.replaceChildren();
}

// The prompt for an access token, in a browser user's words: what a token
// is and who has one; the mechanics (kept in this browser, sent with every
// request) are api.js's.
function tokenPrompt() {
  const input = h('input', {
    type: 'password',
    id: 'token-input',
    autocomplete: 'off',
    spellcheck: 'false',
  });
  return h(
    'form',
    {
      class: 'token-form',
      onsubmit: (e) => {
        e.preventDefault();
        setToken(input.value);
        window.location.reload();
      },
    },
    h(
      'p',
      { id: 'token-help', class: 'token-help' },
      'An access token is a long password made for one person or tablet. ',
      'Ask whoever runs the Reenact server for one, then paste it here; ',
      'this browser remembers it.',
    ),
    h('label', { class: 'field token-field', for: 'token-input' }, 'Access token'),
    input,
    h('button', { class: 'btn', type: 'submit' }, 'Use token'),
  );
}

// A transient line in #status (live mode, retries).
export function setStatus(text) {
  const el = document.getElementById('status');
  if (!el) return;
  el.textContent = text;
  el.hidden = !text;
}
