// The 3D stage shared by the player and the live preview: renderer, camera
// (horizontal field of view fixed, like the server's renderer), orbit/pinch
// controls, the teacher's turn about the vertical through its mean
// position, the mirror image, a floor grid at y = 0 (to judge a squat's
// depth or a step's length by), the frame-rate count, and AR placement.

import {
  Color,
  DirectionalLight,
  HemisphereLight,
  GridHelper,
  Group,
  MathUtils,
  PerspectiveCamera,
  Scene,
  SRGBColorSpace,
  Vector3,
  WebGLRenderer,
} from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import {
  faceCameraYawDeg,
  framingOf,
  orbitDegPerPx,
  orbitRotateSpeed,
  roundMicro,
  verticalFovDeg,
  wrapYawDeg,
} from './lib/geometry.js';
import { showError } from './ui.js';

export const DEFAULT_HFOV_DEG = 50;

// The floor grid: 6 m square, 0.5 m cells, lines faint against the
// background so the teacher stays what the eye goes to.
const FLOOR_SIZE_M = 6;
const FLOOR_CELLS = 12;

export class Stage {
  // container: the element the canvas fills. options.background: '#rrggbb'.
  constructor(container, { background = '#1b1f24', hfovDeg = DEFAULT_HFOV_DEG, antialias = true, floor = true } = {}) {
    this.container = container;
    this.hfovDeg = hfovDeg;
    this.createRenderer(antialias);
    this.createScene(background);
    this.createControls();
    this.createRig();
    this.createFloor(floor);

    this.model = null;
    this.pivot = new Vector3();
    this.facing = new Vector3(0, 0, 1);
    this.yawDeg = 0;
    this.mirror = false;
    this.dirty = true;
    this.width = 1;
    this.height = 1;
    this.renderTimes = [];
    this.onFrame = null; // (dtSeconds) => void, before each render
    this.homeView = null;

    this.resizeObserver = new ResizeObserver(() => this.resize());
    this.resizeObserver.observe(container);
    this.resize();
    this.lastTick = performance.now();
    this.renderer.setAnimationLoop((time, xrFrame) => this.tick(time, xrFrame));
  }

  // The renderer and its canvas (#view), first in the container; a lost
  // graphics context is an error with a reload button.
  createRenderer(antialias) {
    this.renderer = new WebGLRenderer({ antialias, alpha: true });
    this.renderer.outputColorSpace = SRGBColorSpace;
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.canvas = this.renderer.domElement;
    this.canvas.id = 'view';
    this.canvas.setAttribute('role', 'img');
    this.canvas.setAttribute('aria-label', '3D view of the teacher');
    this.container.prepend(this.canvas);
    this.canvas.addEventListener('webglcontextlost', (e) => {
      e.preventDefault();
      showError('The 3D view was lost (the graphics context was reset).', {
        retry: () => window.location.reload(),
        retryLabel: 'Reload',
      });
    });
  }

  // The scene, its background, lights and the camera.
  createScene(background) {
    this.scene = new Scene();
    this.background = new Color(background);
    this.scene.background = this.background;
    // Lights for lit materials (the live preview's grey body); the
    // reenactments' textured materials are unlit.
    this.scene.add(new HemisphereLight(0xffffff, 0x444444, 2.2));
    const key = new DirectionalLight(0xffffff, 1.6);
    key.position.set(1.5, 3, 2.5);
    this.scene.add(key);
    this.camera = new PerspectiveCamera(40, 16 / 9, 0.05, 100);
    this.camera.position.set(0, 1.2, 4);
  }

  // Orbit, pinch-zoom and pan about the actor.
  createControls() {
    this.controls = new OrbitControls(this.camera, this.canvas);
    // Damped: a drag glides to a stop rather than halting under the finger
    // (tick() calls update() every frame while it glides).
    this.controls.enableDamping = true;
    this.controls.dampingFactor = 0.12;
    this.controls.screenSpacePanning = true;
    this.controls.minDistance = 0.3;
    this.controls.maxDistance = 30;
    this.controls.target.set(0, 1, 0);
    this.controls.addEventListener('change', () => this.invalidate());
    // In the mirror image a drag to the right still turns and pans the view
    // to the right as the user sees it.
    for (const name of ['_rotateLeft', '_panLeft']) {
      const original = this.controls[name];
      if (typeof original !== 'function') continue;
      this.controls[name] = (amount, ...rest) => original.call(this.controls, this.mirror ? -amount : amount, ...rest);
    }
    // Until the user moves the view, a resize frames the actor anew.
    this.atHome = false;
    this.framedMotion = null;
    this.controls.addEventListener('start', () => {
      this.atHome = false;
    });
  }

  // placement (AR: the hit pose) > rig (turn about the vertical through
  // the actor's mean) > offset (back to the model's own frame) > model.
  createRig() {
    this.placement = new Group();
    this.rig = new Group();
    this.offset = new Group();
    this.placement.add(this.rig);
    this.rig.add(this.offset);
    this.scene.add(this.placement);
  }

  // The floor: y = 0 of the reenactment's frame, under the actor's mean
  // position; it turns with the AR placement, not with the teacher.
  createFloor(visible) {
    this.floor = new GridHelper(FLOOR_SIZE_M, FLOOR_CELLS, 0x8a96a3, 0x56606b);
    for (const m of Array.isArray(this.floor.material) ? this.floor.material : [this.floor.material]) {
      m.transparent = true;
      m.opacity = 0.45;
      m.depthWrite = false;
    }
    this.floor.renderOrder = -1;
    this.floor.visible = !!visible;
    this.placement.add(this.floor);
  }

  setBackground(hex) {
    this.background.set(hex);
    this.invalidate();
  }

  invalidate() {
    this.dirty = true;
  }

  resize() {
    const w = Math.max(1, this.container.clientWidth);
    const h = Math.max(1, this.container.clientHeight);
    if (this.renderer.xr.isPresenting) return;
    this.width = w;
    this.height = h;
    this.renderer.setSize(w, h, true);
    this.controls.rotateSpeed = orbitRotateSpeed(w, h);
    this.camera.aspect = w / h;
    this.camera.fov = verticalFovDeg(this.hfovDeg, w / h);
    this.camera.updateProjectionMatrix();
    if (this.atHome && this.framedMotion) this.frame(this.framedMotion);
    this.invalidate();
  }

  // Replaces the model. `motion`: analyseMotion's result (mean, extent,
  // floorY, facing).
  setModel(object, motion) {
    if (this.model && this.model !== object) {
      this.offset.remove(this.model);
      disposeObject(this.model);
    }
    this.model = object;
    this.offset.add(object);
    if (motion) {
      this.pivot.set(motion.mean.x, 0, motion.mean.z);
      this.facing.copy(motion.facing);
      this.rig.position.copy(this.pivot);
      this.floor.position.set(this.pivot.x, 0, this.pivot.z);
      this.offset.position.set(-this.pivot.x, 0, -this.pivot.z);
    }
    this.invalidate();
  }

  // Camera in front of the actor (along its facing), framing `extent` (a
  // Box3 in the model's frame) over the whole motion.
  frame(motion) {
    this.framedMotion = motion;
    this.homeView = framing(motion, this.hfovDeg, this.camera.aspect);
    this.resetView();
  }

  resetView() {
    if (!this.homeView) return;
    // A glide still under way would carry the view off home again: with
    // damping off, one update spends what is left of it at once.
    const damping = this.controls.enableDamping;
    this.controls.enableDamping = false;
    this.controls.update();
    this.camera.position.copy(this.homeView.eye);
    this.controls.target.copy(this.homeView.target);
    this.camera.lookAt(this.homeView.target);
    this.controls.update();
    this.controls.enableDamping = damping;
    this.atHome = true;
    this.invalidate();
  }

  setYaw(deg) {
    const d = wrapYawDeg(deg);
    this.yawDeg = d;
    this.rig.rotation.y = MathUtils.degToRad(d);
    this.invalidate();
    return d;
  }

  // The turn that makes the teacher face the camera.
  faceCameraYaw() {
    const pivotWorld = this.rig.getWorldPosition(new Vector3());
    const toCamera = this.camera.position.clone().sub(pivotWorld);
    if (this.renderer.xr.isPresenting) {
      const xrCamera = this.renderer.xr.getCamera();
      toCamera.copy(new Vector3().setFromMatrixPosition(xrCamera.matrixWorld)).sub(pivotWorld);
    }
    return faceCameraYawDeg(toCamera, this.facing, this.placement.rotation.y);
  }

  setFloor(on) {
    this.floor.visible = !!on;
    this.invalidate();
    return this.floor.visible;
  }

  setMirror(on) {
    this.mirror = !!on;
    this.canvas.classList.toggle('mirrored', this.mirror);
    document.body.classList.toggle('mirror', this.mirror);
  }

  tick(time, xrFrame) {
    const now = performance.now();
    const dt = Math.min(0.25, Math.max(0, (now - this.lastTick) / 1000));
    this.lastTick = now;
    if (this.onFrame) this.onFrame(dt, xrFrame);
    // Damping: the view glides on after a drag ('change' marks it dirty).
    if (!this.renderer.xr.isPresenting) this.controls.update();
    if (!this.dirty && !this.renderer.xr.isPresenting) return;
    this.dirty = false;
    this.renderer.render(this.scene, this.camera);
    this.renderTimes.push(now);
    while (this.renderTimes.length && now - this.renderTimes[0] > 1000) this.renderTimes.shift();
  }

  // Rendered frames over the last second.
  fps() {
    const now = performance.now();
    while (this.renderTimes.length && now - this.renderTimes[0] > 1000) this.renderTimes.shift();
    return this.renderTimes.length;
  }

  cameraInfo() {
    const e = this.camera.position;
    const t = this.controls.target;
    return {
      eye: [e.x, e.y, e.z].map(roundMicro),
      target: [t.x, t.y, t.z].map(roundMicro),
      hfov_deg: this.hfovDeg,
      width: this.width,
      height: this.height,
      mirror: this.mirror,
      floor: { visible: this.floor.visible, y: this.floor.position.y },
      orbit_deg_per_px: orbitDegPerPx(this.width),
    };
  }
}

// A camera in front of the actor (along its facing, slightly above),
// looking at its mean position at mid-height and framing `extent` (its
// bounds over the whole motion): {eye, target} (Vector3).
export function framing(motion, hfovDeg, aspect) {
  const { extent, mean, facing } = motion;
  const { eye, target } = framingOf(extent, mean, facing, hfovDeg, aspect);
  return { eye: new Vector3(eye.x, eye.y, eye.z), target: new Vector3(target.x, target.y, target.z) };
}

export function disposeObject(object) {
  object.traverse((o) => {
    if (o.geometry) o.geometry.dispose();
    const materials = o.material ? (Array.isArray(o.material) ? o.material : [o.material]) : [];
    for (const m of materials) {
      for (const value of Object.values(m)) if (value && value.isTexture) value.dispose();
      m.dispose();
    }
  });
}
