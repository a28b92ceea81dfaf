import assert from 'node:assert/strict';
import { test } from 'node:test';
import { ApiError } from '../src/lib/errors.js';
import { GLB_MAGIC, checkGlb, glbProblem, joinChunks, loadingText } from '../src/lib/glb.js';

// A minimal .glb: the 12-byte header and a JSON chunk `json`, its length
// field `declared` (default: the true length).
function glb(json = '{"asset":{"version":"2.0"}}', declared = null) {
  const padded = json.padEnd(Math.ceil(json.length / 4) * 4, ' ');
  const bytes = new Uint8Array(12 + 8 + padded.length);
  const view = new DataView(bytes.buffer);
  view.setUint32(0, GLB_MAGIC, true);
  view.setUint32(4, 2, true);
  view.setUint32(8, declared === null ? bytes.length : declared, true);
  view.setUint32(12, padded.length, true);
  view.setUint32(16, 0x4e4f534a, true); // 'JSON'
  bytes.set(new TextEncoder().encode(padded), 20);
  return bytes.buffer;
}

test('the magic is "glTF" read as a little-endian word', () => {
  assert.equal(new TextDecoder().decode(new Uint8Array(new Uint32Array([GLB_MAGIC]).buffer)), 'glTF');
});

test('a whole glb passes', () => {
  assert.equal(glbProblem(glb()), '');
  assert.doesNotThrow(() => checkGlb(glb()));
});

test('a file shorter than the headers is too short', () => {
  assert.equal(glbProblem(new ArrayBuffer(19)), 'The model is 19 bytes: too short to be a glTF file.');
});

test('a file without the magic is not a binary glTF', () => {
  const bytes = new Uint8Array(glb());
  bytes[0] = 0x7b; // '{': a .gltf JSON file
  assert.equal(glbProblem(bytes.buffer), 'The model is not a binary glTF file (bad magic).');
});

test('a cut-off download is told by its length field', () => {
  const whole = glb();
  const cut = whole.slice(0, whole.byteLength - 4);
  assert.equal(
    glbProblem(cut),
    `The model is truncated or damaged: ${cut.byteLength} bytes received, the file says ${whole.byteLength}.`,
  );
  assert.match(glbProblem(glb(undefined, 4096)), /the file says 4096\.$/);
});

test('checkGlb throws a DATA_LOSS ApiError', () => {
  assert.throws(
    () => checkGlb(new ArrayBuffer(4)),
    (e) => e instanceof ApiError && e.code === 'DATA_LOSS' && e.status === 200 && /4 bytes/.test(e.message),
  );
});

test('joinChunks concatenates the chunks in order', () => {
  const joined = joinChunks([Uint8Array.from([1, 2]), new Uint8Array(0), Uint8Array.from([3, 4, 5])]);
  assert.ok(joined instanceof ArrayBuffer);
  assert.deepEqual(Array.from(new Uint8Array(joined)), [1, 2, 3, 4, 5]);
  assert.equal(joinChunks([]).byteLength, 0);
});

test('loadingText: a percentage with a known length, else megabytes', () => {
  assert.equal(loadingText(512, 2048), 'Loading the reenactment… 25 %');
  assert.equal(loadingText(2500000, 0), 'Loading the reenactment… 2.5 MB');
});
