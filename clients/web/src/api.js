// The server's HTTP API (/api/v1): authenticated fetches, JSON errors, the
// access token (URL fragment #token=..., kept in localStorage).

const TOKEN_KEY = 'reenact.token';

export class ApiError extends Error {
  // status: HTTP status (0: the server could not be reached); code: the
  // server's error code (gRPC status name) when it sent one.
  constructor(status, code, message) {
    super(message);
    this.name = 'ApiError';
    this.status = status;
    this.code = code;
  }
}

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

// The body of a reenactment's model.glb, checked against its own length
// field (a cut-off download is an error here, not a half-drawn body).
export async function fetchGlb(id, onProgress) {
  const response = await apiFetch(`/api/v1/reenactments/${encodeURIComponent(id)}/model.glb`);
  const total = Number(response.headers.get('Content-Length')) || 0;
  let buffer;
  if (response.body && onProgress) {
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
    const bytes = new Uint8Array(received);
    let at = 0;
    for (const c of chunks) {
      bytes.set(c, at);
      at += c.byteLength;
    }
    buffer = bytes.buffer;
  } else {
    buffer = await response.arrayBuffer();
  }
  checkGlb(buffer);
  return buffer;
}

// Throws ApiError when `buffer` is not a whole binary glTF.
export function checkGlb(buffer) {
  if (buffer.byteLength < 20) {
    throw new ApiError(200, 'DATA_LOSS', `The model is ${buffer.byteLength} bytes: too short to be a glTF file.`);
  }
  const view = new DataView(buffer);
  if (view.getUint32(0, true) !== 0x46546c67) {
    throw new ApiError(200, 'DATA_LOSS', 'The model is not a binary glTF file (bad magic).');
  }
  const declared = view.getUint32(8, true);
  if (declared !== buffer.byteLength) {
    throw new ApiError(
      200,
      'DATA_LOSS',
      `The model is truncated or damaged: ${buffer.byteLength} bytes received, the file says ${declared}.`,
    );
  }
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
  if (e instanceof ApiError) {
    if (e.status === 401) {
      // The server's own words name the command line's flags; a browser
      // user needs to know what a token is and who has one.
      return getToken()
        ? 'The access token this browser has is not one the server knows (mistyped, or withdrawn). ' +
            'Ask whoever runs the Reenact server for a new one.'
        : 'This Reenact server lets in only people with an access token.';
    }
    if (e.status === 403) return `This token's role may not do this (${e.message}).`;
    if (e.status === 404) return `Not found: ${e.message}`;
    if (e.status === 0) return e.message;
    return e.message;
  }
  return (e && e.message) || String(e);
}
