// The live body: the skinned mesh the server sends (binary glb) posed by
// each frame's joint rotations and root position, framed on its first
// pose.

import { MeshLambertMaterial } from 'three';
import { describeError } from '../api.js';
import { analyseMotion, parseGlb } from '../model.js';
import { setStatus } from '../ui.js';

// The first skinned mesh under `object`, or null.
function firstSkinnedMesh(object) {
  let skinned = null;
  object.traverse((o) => {
    if (o.isSkinnedMesh && !skinned) skinned = o;
  });
  return skinned;
}

// The preview redraws at the capture's pace: an untextured body gets a
// cheap diffuse material.
function useDiffuseMaterial(mesh) {
  const old = mesh.material;
  if (old && !old.map) {
    mesh.material = new MeshLambertMaterial({ color: old.color ? old.color.clone() : 0xb0b0b0 });
    old.dispose();
  }
}

export class LiveBody {
  constructor(stage) {
    this.stage = stage;
    this.bones = null;
    this.framed = false;
    this.latest = null; // the latest frame message
    this.pending = null; // a frame that came while the mesh was being read
    this.loads = Promise.resolve();
  }

  // A frame message: poses the body, or keeps it for the mesh to come.
  receive(m) {
    this.latest = m;
    if (this.bones) this.pose(m);
    else this.pending = m;
  }

  // A mesh (a glb ArrayBuffer): read after those before it, then posed by
  // the latest frame.
  loadMesh(buffer) {
    this.loads = this.loads.then(async () => {
      try {
        await this.useMesh(buffer);
      } catch (e) {
        setStatus(`The live mesh could not be read: ${describeError(e)}`);
      }
    });
  }

  async useMesh(buffer) {
    const { gltf } = await parseGlb(buffer);
    const skinned = firstSkinnedMesh(gltf.scene);
    if (!skinned) throw new Error('the live mesh has no skin');
    useDiffuseMaterial(skinned);
    const replacing = this.stage.model !== null;
    this.bones = skinned.skeleton.bones;
    const motion = analyseMotion(gltf.scene, null, 1);
    this.stage.setModel(gltf.scene, motion);
    if (!replacing) this.stage.frame(motion);
    this.framed = replacing;
    const p = this.pending || this.latest;
    this.pending = null;
    if (p) this.pose(p);
  }

  pose(message) {
    const { bones } = this;
    if (!bones) return;
    const rotations = message.local_rotations || [];
    const n = Math.min(bones.length, rotations.length);
    for (let j = 0; j < n; ++j) {
      const q = rotations[j];
      bones[j].quaternion.set(q[0], q[1], q[2], q[3]);
    }
    const root = message.root_position_m;
    if (root && bones[0]) bones[0].position.set(root[0], root[1], root[2]);
    if (!this.framed) {
      this.framed = true;
      this.frameActor();
    }
    this.stage.invalidate();
  }

  // Frames the actor as posed now, with room for it to move.
  frameActor() {
    const { stage } = this;
    if (!stage.model) return;
    const motion = analyseMotion(stage.model, null, 1);
    motion.extent.expandByVector({ x: 0.3, y: 0.05, z: 0.3 });
    stage.setModel(stage.model, motion);
    stage.frame(motion);
  }
}
