// The errors the app shows: ApiError, and the sentence a person reads for
// one.

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

// Whether `e` is the server refusing this token (401) or its role (403):
// retrying will not help.
export function isAccessError(e) {
  return e instanceof ApiError && (e.status === 401 || e.status === 403);
}

// A sentence for an error, with what the user can do about it. `hasToken`:
// whether this browser holds an access token (a 401 reads differently).
export function errorSentence(e, hasToken) {
  if (e instanceof ApiError) {
    if (e.status === 401) {
      // The server's own words name the command line's flags; a browser
      // user needs to know what a token is and who has one.
      return hasToken
        ? 'The access token this browser has is not one the server knows (mistyped, or withdrawn). ' +
            'Ask whoever runs the Reenact server for a new one.'
        : 'This Reenact server lets in only people with an access token.';
    }
    if (e.status === 403) return `This token's role may not do this (${e.message}).`;
    if (e.status === 404) return `Not found: ${e.message}`;
    return e.message;
  }
  return (e && e.message) || String(e);
}
