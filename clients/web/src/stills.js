// Stills of reenactments for the library: drawn here from each model.glb by
// one shared offscreen renderer, one at a time, cached for the page's life.

import { AnimationMixer, Color, PerspectiveCamera, Scene, SRGBColorSpace, WebGLRenderer } from 'three';
import { fetchGlb } from './api.js';
import { analyseMotion, parseGlb } from './model.js';
import { verticalFovDeg } from './lib/geometry.js';
import { disposeObject, framing } from './stage.js';

const WIDTH = 480;
const HEIGHT = 360;
const HFOV_DEG = 50;

let renderer = null;
const cache = new Map(); // id -> Promise<string> (an object URL)
let queue = Promise.resolve();

function getRenderer() {
  if (!renderer) {
    const canvas = document.createElement('canvas');
    canvas.width = WIDTH;
    canvas.height = HEIGHT;
    renderer = new WebGLRenderer({ canvas, antialias: true, alpha: false, preserveDrawingBuffer: true });
    renderer.outputColorSpace = SRGBColorSpace;
    renderer.setPixelRatio(1);
    renderer.setSize(WIDTH, HEIGHT, false);
  }
  return renderer;
}

async function draw(id) {
  const buffer = await fetchGlb(id);
  const { gltf } = await parseGlb(buffer);
  const model = gltf.scene;
  const clip = gltf.animations[0] || null;
  const motion = analyseMotion(model, clip, 12);
  // The pose a third of the way in: mid-action for most takes.
  const mixer = new AnimationMixer(model);
  if (clip) {
    mixer.clipAction(clip).play();
    mixer.setTime(clip.duration / 3);
  }
  const scene = new Scene();
  scene.background = new Color('#2a3038');
  scene.add(model);
  const camera = new PerspectiveCamera(verticalFovDeg(HFOV_DEG, WIDTH / HEIGHT), WIDTH / HEIGHT, 0.05, 100);
  const { eye, target } = framing(motion, HFOV_DEG, WIDTH / HEIGHT);
  camera.position.copy(eye);
  camera.lookAt(target);
  const r = getRenderer();
  r.render(scene, camera);
  const blob = await new Promise((resolve, reject) =>
    r.domElement.toBlob((b) => (b ? resolve(b) : reject(new Error('no image'))), 'image/jpeg', 0.85),
  );
  mixer.stopAllAction();
  mixer.uncacheRoot(model);
  scene.remove(model);
  disposeObject(model);
  r.renderLists.dispose();
  return URL.createObjectURL(blob);
}

// An object URL of the still of reenactment `id` (one draw at a time).
export function still(id) {
  if (!cache.has(id)) {
    const p = queue.then(() => draw(id));
    queue = p.catch(() => {});
    cache.set(id, p);
    p.catch(() => cache.delete(id));
  }
  return cache.get(id);
}
