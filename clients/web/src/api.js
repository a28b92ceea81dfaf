// The server's HTTP API (/api/v1): authenticated fetches, JSON errors, the
// access token (URL fragment #token=..., kept in localStorage).

import { ApiError, errorSentence } from './lib/errors.js';
import { checkGlb, joinChunks } from './lib/glb.js';

export { ApiError };

const TOKEN_KEY = 'reenact.token';

// Moves a token from the address bar's fragment (#token=...) into
// localStorage and removes it from the address bar and the history entry.
export function adoptTokenFromFragment() {
  const hash = window.location.hash.replace(/^#/, '');
  if (!hash) return;
  const params = new URLSearchParams(hash);
  const token = params.get('token');
  if (token === null) return;
  setToken(token);
  params.delete('token');
  const rest = params.toString();
  const url = window.location.pathname + window.location.search + (rest ? `#${rest}` : '');
  window.history.replaceState(window.history.state, '', url);
}

export function getToken() {
  try {
    return window.localStorage.getItem(TOKEN_KEY) || '';
  } catch {
    return '';
  }
}

export function setToken(token) {
  try {
    if (token) window.localStorage.setItem(TOKEN_KEY, token.trim());
    else window.localStorage.removeItem(TOKEN_KEY);
  } catch {
    // Private mode without storage: the token lasts for this page only.
  }
}

function authHeaders(extra = {}) {
  const headers = { ...extra };
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  return headers;
}

// An ApiError for a non-2xx response, with the server's message when the
// body is the API's JSON error.
async function errorOf(response) {
  let code = '';
  let message = '';
  try {
    const body = await response.json();
    if (body && body.error) {
      code = body.error.code || '';
      message = body.error.message || '';
    }
  } catch {
    // Not JSON (a proxy's page, say): the status line says enough.
  }
  if (!message) message = `${response.status} ${response.statusText || 'error'}`;
  return new ApiError(response.status, code, message);
}

// fetch() with the token; throws ApiError for network failures and non-2xx
// answers.
export async function apiFetch(path, options = {}) {
  let response;
  try {
    response = await fetch(path, {
      ...options,
      headers: authHeaders(options.headers),
      cache: options.cache || 'no-cache',
    });
  } catch (e) {
    throw new ApiError(0, 'UNAVAILABLE', `The server cannot be reached (${e.message || e}).`);
  }
  if (!response.ok) throw await errorOf(response);
  return response;
}

export async function apiJson(path, options = {}) {
  const response = await apiFetch(path, options);
  try {
    return await response.json();
  } catch (e) {
    throw new ApiError(response.status, 'DATA_LOSS', `The server's answer is not JSON (${e.message}).`);
  }
}

// Every page of a listing that pages with X-Next-Page-Token.
export async function apiJsonAllPages(path, params = {}, maxPages = 100) {
  const items = [];
  let token = '';
  for (let page = 0; page < maxPages; ++page) {
    const query = new URLSearchParams(params);
    if (token) query.set('page_token', token);
    const qs = query.toString();
    const response = await apiFetch(qs ? `${path}?${qs}` : path);
    let batch;
    try {
      batch = await response.json();
    } catch (e) {
      throw new ApiError(response.status, 'DATA_LOSS', `The server's answer is not JSON (${e.message}).`);
    }
    if (!Array.isArray(batch)) {
      throw new ApiError(response.status, 'DATA_LOSS', 'The server answered a listing with something else.');
    }
    items.push(...batch);
    token = response.headers.get('X-Next-Page-Token') || '';
    if (!token) break;
  }
  return items;
}

// The body of a response as an ArrayBuffer, read in chunks with
// onProgress(received, total) after each (total: Content-Length, 0 when
// unknown).
async function readWithProgress(response, onProgress) {
  const total = Number(response.headers.get('Content-Length')) || 0;
  const reader = response.body.getReader();
  const chunks = [];
  let received = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    chunks.push(value);
    received += value.byteLength;
    onProgress(received, total);
  }
  return joinChunks(chunks);
}

// The body of a reenactment's model.glb, checked against its own length
// field (a cut-off download is an error here, not a half-drawn body).
export async function fetchGlb(id, onProgress) {
  const response = await apiFetch(`/api/v1/reenactments/${encodeURIComponent(id)}/model.glb`);
  const buffer =
    response.body && onProgress ? await readWithProgress(response, onProgress) : await response.arrayBuffer();
  checkGlb(buffer);
  return buffer;
}

// The WebSocket URL of a path on this server, with the token as a query.
export function webSocketUrl(path) {
  const scheme = window.location.protocol === 'https:' ? 'wss:' : 'ws:';
  const token = getToken();
  const query = token ? `?access_token=${encodeURIComponent(token)}` : '';
  return `${scheme}//${window.location.host}${path}${query}`;
}

// A sentence for an error, with what the user can do about it.
export function describeError(e) {
  return errorSentence(e, !!getToken());
}
