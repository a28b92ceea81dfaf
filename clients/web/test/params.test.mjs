import assert from 'node:assert/strict';
import { test } from 'node:test';
import { backgroundFromParams, numberParam, playerParams, routeOf, viewParams } from '../src/lib/params.js';

const q = (s) => new URLSearchParams(s);

test('routeOf: the player, the live preview, else the library', () => {
  assert.deepEqual(routeOf(q('?reenactment=r1')), { page: 'player', id: 'r1' });
  assert.deepEqual(routeOf(q('?job=j7')), { page: 'live', id: 'j7' });
  assert.deepEqual(routeOf(q('?reenactment=r1&job=j7')), { page: 'player', id: 'r1' });
  assert.deepEqual(routeOf(q('?reenactment=&job=j7')), { page: 'live', id: 'j7' });
  assert.deepEqual(routeOf(q('')), { page: 'library', id: '' });
});

test('backgroundFromParams takes six hex digits, with or without #', () => {
  assert.equal(backgroundFromParams(q('bg=000000'), '#1b1f24'), '#000000');
  assert.equal(backgroundFromParams(q('bg=%23A0b1C2'), ''), '#A0b1C2');
  assert.equal(backgroundFromParams(q('bg=fff'), '#1b1f24'), '#1b1f24');
  assert.equal(backgroundFromParams(q('bg=red'), ''), '');
  assert.equal(backgroundFromParams(q(''), 'x'), 'x');
});

test('numberParam: a finite number, else null', () => {
  assert.equal(numberParam(q('t=1.5'), 't'), 1.5);
  assert.equal(numberParam(q('t=-2'), 't'), -2);
  assert.equal(numberParam(q('t=abc'), 't'), null);
  assert.equal(numberParam(q('t=Infinity'), 't'), null);
  assert.equal(numberParam(q(''), 't'), null);
  assert.equal(numberParam(q('t='), 't'), 0);
});

test('viewParams: controls and floor on unless 0, the mirror only when 1', () => {
  assert.deepEqual(viewParams(q('')), { controls: true, mirror: false, floor: true });
  assert.deepEqual(viewParams(q('controls=0&mirror=1&floor=0')), { controls: false, mirror: true, floor: false });
  assert.deepEqual(viewParams(q('mirror=yes&floor=no')), { controls: true, mirror: false, floor: true });
});

test('playerParams reads the deep link', () => {
  const link = playerParams(q('t=1.25&paused=1&yaw=-30&speed=0.5&a=1&b=2&appearance=0'));
  assert.equal(link.t, 1.25);
  assert.equal(link.paused, true);
  assert.equal(link.yaw, -30);
  assert.equal(link.speed, 0.5);
  assert.equal(link.a, 1);
  assert.equal(link.b, 2);
  assert.equal(link.appearance, false);
  const none = playerParams(q(''));
  assert.deepEqual([none.t, none.yaw, none.speed, none.a, none.b], [null, null, null, null, null]);
  assert.equal(none.paused, false);
  assert.equal(none.appearance, true);
});
