// Reenactment glTF files: parsing, the root's extras, and where the actor
// is (mean position, extent over time, facing).

import { AnimationMixer, Box3, Vector3 } from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { ApiError } from './lib/errors.js';

const loader = new GLTFLoader();

// Parses a .glb ArrayBuffer. Resolves {gltf, info}; info holds the root
// node's extras (reenactment_id, take_id, method, fps, frame_count).
export async function parseGlb(buffer) {
  let gltf;
  try {
    gltf = await loader.parseAsync(buffer, '');
  } catch (e) {
    throw new ApiError(200, 'DATA_LOSS', `The model cannot be read: ${(e && e.message) || e}`);
  }
  const json = gltf.parser && gltf.parser.json;
  const root = json && json.nodes && json.nodes[0];
  const extras = (root && root.extras) || {};
  const info = {
    name: (root && root.name) || '',
    reenactment_id: extras.reenactment_id || '',
    take_id: extras.take_id || '',
    method: extras.method || '',
    fps: Number(extras.fps) || 0,
    frame_count: Number(extras.frame_count) || 0,
  };
  return { gltf, info };
}

const v = new Vector3();

// World bounds of `object` as drawn now (skinned meshes with their current
// pose, every `stride`-th vertex).
function currentBounds(object, box) {
  box.makeEmpty();
  object.updateMatrixWorld(true);
  object.traverse((o) => {
    if (!o.isMesh || !o.geometry || !o.geometry.attributes.position) return;
    const position = o.geometry.attributes.position;
    if (o.isSkinnedMesh) {
      const stride = Math.max(1, Math.floor(position.count / 4000));
      for (let i = 0; i < position.count; i += stride) {
        o.getVertexPosition(i, v);
        v.applyMatrix4(o.matrixWorld);
        box.expandByPoint(v);
      }
    } else {
      if (!o.geometry.boundingBox) o.geometry.computeBoundingBox();
      const b = o.geometry.boundingBox.clone().applyMatrix4(o.matrixWorld);
      box.union(b);
    }
  });
  return box;
}

// Where the actor is over the clip: the mean of its bounding boxes' centres
// (`mean`), their union (`extent`), the lowest point (`floorY`), and the
// horizontal direction it faces on average (`facing`, unit, from its
// left/right joint or part pairs; +Z when it has none). Leaves the model at
// time 0.
export function analyseMotion(object, clip, samples = 24) {
  const mixer = new AnimationMixer(object);
  if (clip) mixer.clipAction(clip).play();
  const duration = clip ? clip.duration : 0;
  const n = clip && duration > 0 ? samples : 1;
  const extent = new Box3();
  const box = new Box3();
  const mean = new Vector3();
  const facing = new Vector3();
  const centre = new Vector3();
  const pairs = sidePairs(object);
  const left = new Vector3();
  const right = new Vector3();
  let counted = 0;
  for (let i = 0; i < n; ++i) {
    const t = n > 1 ? (duration * i) / (n - 1) : 0;
    mixer.setTime(t);
    currentBounds(object, box);
    if (box.isEmpty()) continue;
    extent.union(box);
    mean.add(box.getCenter(centre));
    ++counted;
    for (const [l, r] of pairs) {
      l.getWorldPosition(left);
      r.getWorldPosition(right);
      // Facing = (left - right) x up: a person facing +Z has their left at +X.
      const d = left.sub(right);
      facing.x += -d.z;
      facing.z += d.x;
    }
  }
  mixer.setTime(0);
  mixer.stopAllAction();
  mixer.uncacheRoot(object);
  if (counted > 0) mean.divideScalar(counted);
  facing.y = 0;
  if (facing.lengthSq() < 1e-12) facing.set(0, 0, 1);
  facing.normalize();
  return { mean, extent, floorY: extent.isEmpty() ? 0 : extent.min.y, facing };
}

// Left/right node pairs (HipLeft/HipRight, thigh_left/thigh_right, ...).
function sidePairs(object) {
  const byName = new Map();
  object.traverse((o) => {
    if (o.name) byName.set(o.name.toLowerCase(), o);
  });
  const pairs = [];
  for (const [name, node] of byName) {
    if (!/left/.test(name)) continue;
    if (!/^(hip|shoulder|thigh|upper_arm)/.test(name)) continue;
    const other = byName.get(name.replace('left', 'right'));
    if (other) pairs.push([node, other]);
  }
  return pairs;
}
