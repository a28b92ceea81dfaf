// Binary glTF (.glb) checks: a reenactment's model.glb must be whole before
// it is parsed (a cut-off download is an error, not a half-drawn body).

import { ApiError } from './errors.js';

// 'glTF' read as a little-endian uint32: the first word of every .glb.
export const GLB_MAGIC = 0x46546c67;

// The 12-byte header and the first chunk's 8-byte header.
export const GLB_MIN_BYTES = 20;

// Why `buffer` (an ArrayBuffer) is not a whole binary glTF, or '' when it
// is: too short, a bad magic, or a length field that disagrees with the
// bytes received.
export function glbProblem(buffer) {
  if (buffer.byteLength < GLB_MIN_BYTES) {
    return `The model is ${buffer.byteLength} bytes: too short to be a glTF file.`;
  }
  const view = new DataView(buffer);
  if (view.getUint32(0, true) !== GLB_MAGIC) return 'The model is not a binary glTF file (bad magic).';
  const declared = view.getUint32(8, true);
  if (declared !== buffer.byteLength) {
    return `The model is truncated or damaged: ${buffer.byteLength} bytes received, the file says ${declared}.`;
  }
  return '';
}

// Throws ApiError (DATA_LOSS) when `buffer` is not a whole binary glTF.
export function checkGlb(buffer) {
  const problem = glbProblem(buffer);
  if (problem) throw new ApiError(200, 'DATA_LOSS', problem);
}

// The chunks of a streamed download (Uint8Arrays) as one ArrayBuffer.
export function joinChunks(chunks) {
  const total = chunks.reduce((sum, c) => sum + c.byteLength, 0);
  const bytes = new Uint8Array(total);
  let at = 0;
  for (const c of chunks) {
    bytes.set(c, at);
    at += c.byteLength;
  }
  return bytes.buffer;
}

// What the player says while the model downloads: a percentage when the
// length is known, else megabytes.
export function loadingText(received, total) {
  return total
    ? `Loading the reenactment… ${Math.round((100 * received) / total)} %`
    : `Loading the reenactment… ${(received / 1e6).toFixed(1)} MB`;
}
