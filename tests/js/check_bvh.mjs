// Reads a BVH file with three.js's BVHLoader (an implementation independent
// of Reenact's reader) and measures what an animator's tool would trip over:
//
//   node check_bvh.mjs FILE.bvh [--metres-per-unit S]
//
// Prints one JSON object:
//   bones, end_sites, frames, frame_time_s: what the loader read;
//   zero_length_bones: joints whose bone (to their first child, or to their
//     End Site) is shorter than 1 mm: Blender warns on each and drops it;
//   height_m: the figure's vertical extent in the first frame, in metres
//     (the file's units times S, default 1: what Blender's and three.js's
//     default scale show);
//   excess_jump_deg: over every joint and every pair of consecutive frames,
//     how much farther the file's rotation channels move (the sum of their
//     changes) than the nearest equivalent angles of the same next rotation
//     would (of (a, b, c) and (a + 180, 180 - b, c + 180), each turned by
//     whole multiples of 360 degrees): 0 when the channels are continuous
//     (unwrapped); near 360 where they jump between equivalent angles;
//   max_blend_error_deg: over the pairs of consecutive frames whose rotation
//     turns by less than 15 degrees, the angle between the rotation a player
//     gets by blending the channels linearly halfway and the true halfway
//     rotation (the slerp of the loader's quaternions): small where the
//     channels are continuous, up to 180 where they jump;
//   max_turn_deg: the largest turn of a joint from one frame to the next
//     (the motion itself; not checked);
//   channel_jumps_over_90: channel values that change by more than 90
//     degrees from one frame to the next.
// Exit status 1 when a bone has zero length, excess_jump_deg > 1 or
// max_blend_error_deg > 5; 2 when the file does not read.
import fs from 'node:fs';
import { Euler, Quaternion, Vector3 } from 'three';
import { BVHLoader } from 'three/examples/jsm/loaders/BVHLoader.js';

function fail(message) {
  console.log(JSON.stringify({ error: message }));
  process.exit(2);
}

const args = process.argv.slice(2);
const file = args[0];
let metresPerUnit = 1;
for (let i = 1; i < args.length; ++i) {
  if (args[i] === '--metres-per-unit') metresPerUnit = Number(args[++i]);
  else fail(`unknown argument ${args[i]}`);
}
if (!file || !(metresPerUnit > 0)) fail('usage: node check_bvh.mjs FILE.bvh [--metres-per-unit S]');

let text;
try {
  text = fs.readFileSync(file, 'utf8');
} catch (e) {
  fail(`cannot read ${file}: ${e.message}`);
}
let result;
try {
  result = new BVHLoader().parse(text);
} catch (e) {
  fail(`BVHLoader: ${e.message}`);
}
const bones = result.skeleton.bones;
const joints = bones.filter((b) => b.name !== 'ENDSITE');

// Bone lengths: a joint's bone runs to its first child (joint or End Site).
const zeroLength = [];
for (const bone of joints) {
  const child = bone.children.find((c) => c.isBone);
  if (child && child.position.length() * metresPerUnit < 1e-3) zeroLength.push(bone.name);
}

// The channels as the file lists them (the loader converts them to
// quaternions and keeps no Euler values): per joint its rotation channel
// order, then the frames' numbers.
const lines = text.split(/\r?\n/);
const channelsOf = [];
let motionLine = -1;
for (let i = 0; i < lines.length; ++i) {
  const tokens = lines[i].trim().split(/\s+/);
  if (tokens[0] === 'CHANNELS') channelsOf.push(tokens.slice(2));
  if (tokens[0] === 'MOTION') {
    motionLine = i;
    break;
  }
}
if (motionLine < 0 || channelsOf.length !== joints.length) fail('channels and joints disagree');
const frames = [];
for (let i = motionLine + 3; i < lines.length; ++i) {
  if (lines[i].trim() === '') continue;
  frames.push(lines[i].trim().split(/\s+/).map(Number));
}

// Each joint's rotation at a frame from its Euler channels, in the file's
// order (BVH: the listed order is the order of multiplication).
function rotationOf(joint, values) {
  const order = channelsOf[joint].filter((c) => c.endsWith('rotation')).map((c) => c[0]).join('');
  const angles = { X: 0, Y: 0, Z: 0 };
  for (const [channel, value] of values) angles[channel[0]] = (value * Math.PI) / 180;
  return new Quaternion().setFromEuler(new Euler(angles.X, angles.Y, angles.Z, order));
}

// The channel triple (radians, file order) of the representation of
// rotation `b` nearest `a` (see excess_jump_deg).
function nearestEquivalent(a, b) {
  let best = null;
  let bestDistance = Infinity;
  for (const candidate of [b, [b[0] + Math.PI, Math.PI - b[1], b[2] + Math.PI]]) {
    const shifted = candidate.map((v, k) => v + 2 * Math.PI * Math.round((a[k] - v) / (2 * Math.PI)));
    const distance = shifted.reduce((sum, v, k) => sum + Math.abs(v - a[k]), 0);
    if (distance < bestDistance) {
      bestDistance = distance;
      best = shifted;
    }
  }
  return bestDistance;
}

const toRad = (d) => (d * Math.PI) / 180;
const toDeg = (r) => (r * 180) / Math.PI;
let maxBlendDeg = 0;
let excessDeg = 0;
let maxTurnDeg = 0;
let jumps = 0;
for (let f = 0; f + 1 < frames.length; ++f) {
  let at = 0;
  for (let j = 0; j < joints.length; ++j) {
    const a = [];
    const b = [];
    const mid = [];
    for (const channel of channelsOf[j]) {
      const va = frames[f][at];
      const vb = frames[f + 1][at];
      ++at;
      if (!channel.endsWith('rotation')) continue;
      if (Math.abs(vb - va) > 90) ++jumps;
      a.push([channel, va]);
      b.push([channel, vb]);
      mid.push([channel, (va + vb) / 2]);
    }
    if (mid.length !== 3) continue;
    const qa = rotationOf(j, a);
    const qb = rotationOf(j, b);
    const turn = toDeg(qa.angleTo(qb));
    maxTurnDeg = Math.max(maxTurnDeg, turn);
    const ra = a.map(([, v]) => toRad(v));
    const rb = b.map(([, v]) => toRad(v));
    const moved = rb.reduce((sum, v, k) => sum + Math.abs(v - ra[k]), 0);
    excessDeg = Math.max(excessDeg, toDeg(moved - nearestEquivalent(ra, rb)));
    if (turn < 15) {
      const truth = qa.clone().slerp(qb, 0.5);
      maxBlendDeg = Math.max(maxBlendDeg, toDeg(truth.angleTo(rotationOf(j, mid))));
    }
  }
}

// The first frame's pose through the loader's own tracks.
for (const track of result.clip.tracks) {
  const [name, property] = track.name.split('.');
  const bone = joints.find((b) => b.name === name);
  if (!bone) continue;
  if (property === 'position') bone.position.fromArray(track.values, 0);
  if (property === 'quaternion') bone.quaternion.fromArray(track.values, 0);
}
bones[0].updateMatrixWorld(true);
let low = Infinity;
let high = -Infinity;
const p = new Vector3();
for (const bone of bones) {
  bone.getWorldPosition(p);
  low = Math.min(low, p.y);
  high = Math.max(high, p.y);
}

const report = {
  bones: joints.length,
  end_sites: bones.length - joints.length,
  frames: frames.length,
  frame_time_s: result.clip.duration / Math.max(1, frames.length - 1),
  zero_length_bones: zeroLength,
  height_m: (high - low) * metresPerUnit,
  excess_jump_deg: excessDeg,
  max_blend_error_deg: maxBlendDeg,
  max_turn_deg: maxTurnDeg,
  channel_jumps_over_90: jumps,
};
console.log(JSON.stringify(report));
process.exit(zeroLength.length > 0 || excessDeg > 1 || maxBlendDeg > 5 ? 1 : 0);
