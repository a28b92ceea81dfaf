import assert from 'node:assert/strict';
import { test } from 'node:test';
import { CONTROL_KEYS, KEY_CONTROLS, shortcutOf } from '../src/lib/keys.js';
import { sameIds, watchableJobs } from '../src/lib/listing.js';

test('sameIds: the same ids in any order', () => {
  const shown = new Map([
    ['a', 1],
    ['b', 2],
  ]);
  assert.equal(sameIds([{ id: 'b' }, { id: 'a' }], shown), true);
  assert.equal(sameIds([{ id: 'a' }], shown), false);
  assert.equal(sameIds([{ id: 'a' }, { id: 'c' }], shown), false);
  assert.equal(sameIds([], new Map()), true);
});

test('watchableJobs: live jobs running or queued', () => {
  const jobs = [
    { id: 1, live: true, state: 'running' },
    { id: 2, live: true, state: 'queued' },
    { id: 3, live: true, state: 'succeeded' },
    { id: 4, live: false, state: 'running' },
  ];
  assert.deepEqual(
    watchableJobs(jobs).map((j) => j.id),
    [1, 2],
  );
});

test('shortcutOf: Space, the arrows and M, never with a modifier', () => {
  assert.equal(shortcutOf({ key: ' ' }), 'play');
  assert.equal(shortcutOf({ key: 'ArrowLeft' }), 'previous');
  assert.equal(shortcutOf({ key: 'ArrowRight' }), 'next');
  assert.equal(shortcutOf({ key: 'm' }), 'mirror');
  assert.equal(shortcutOf({ key: 'M' }), '');
  assert.equal(shortcutOf({ key: 'x' }), '');
  assert.equal(shortcutOf({ key: ' ', ctrlKey: true }), '');
  assert.equal(shortcutOf({ key: 'm', metaKey: true }), '');
  assert.equal(shortcutOf({ key: 'ArrowLeft', altKey: true }), '');
  assert.equal(shortcutOf({ key: ' ', defaultPrevented: true }), '');
});

test('focused controls keep Space and Enter', () => {
  assert.deepEqual([...CONTROL_KEYS], [' ', 'Enter']);
  for (const selector of ['button', 'a[href]', 'summary', '[role="button"]', '[role="slider"]', '[role="option"]']) {
    assert.ok(KEY_CONTROLS.split(', ').includes(selector), selector);
  }
});
