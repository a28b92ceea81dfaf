import assert from 'node:assert/strict';
import { test } from 'node:test';
import { ApiError, errorSentence, isAccessError } from '../src/lib/errors.js';

test('ApiError carries the status and the code', () => {
  const e = new ApiError(404, 'NOT_FOUND', 'no reenactment r1');
  assert.ok(e instanceof Error);
  assert.equal(e.name, 'ApiError');
  assert.equal(e.status, 404);
  assert.equal(e.code, 'NOT_FOUND');
  assert.equal(e.message, 'no reenactment r1');
});

test('a 401 reads differently with and without a token', () => {
  const e = new ApiError(401, 'UNAUTHENTICATED', 'pass --token');
  assert.equal(errorSentence(e, false), 'This Reenact server lets in only people with an access token.');
  assert.match(errorSentence(e, true), /^The access token this browser has is not one the server knows/);
  assert.doesNotMatch(errorSentence(e, true), /--token/);
});

test('403, 404 and other answers', () => {
  assert.equal(
    errorSentence(new ApiError(403, 'PERMISSION_DENIED', 'viewer'), true),
    "This token's role may not do this (viewer).",
  );
  assert.equal(errorSentence(new ApiError(404, 'NOT_FOUND', 'no job'), false), 'Not found: no job');
  assert.equal(
    errorSentence(new ApiError(0, 'UNAVAILABLE', 'The server cannot be reached.'), false),
    'The server cannot be reached.',
  );
  assert.equal(errorSentence(new ApiError(500, 'INTERNAL', 'boom'), false), 'boom');
});

test('plain errors and anything else', () => {
  assert.equal(errorSentence(new Error('bad'), false), 'bad');
  assert.equal(errorSentence('a sentence', false), 'a sentence');
  assert.equal(errorSentence(null, false), 'null');
});

test('isAccessError: 401 and 403 only', () => {
  assert.equal(isAccessError(new ApiError(401, '', '')), true);
  assert.equal(isAccessError(new ApiError(403, '', '')), true);
  assert.equal(isAccessError(new ApiError(404, '', '')), false);
  assert.equal(isAccessError(Object.assign(new Error('x'), { status: 401 })), false);
});
