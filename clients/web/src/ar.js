// AR placement (WebXR immersive-ar with hit-test and dom-overlay): a ring
// follows the floor under the screen's centre; a tap puts the teacher there
// at real scale, feet on the floor. The page's controls stay usable in the
// overlay.

import { Mesh, MeshBasicMaterial, RingGeometry, Vector3 } from 'three';

// Why AR cannot start here, or '' when it can be tried.
export async function arUnavailableReason() {
  if (!window.isSecureContext) return 'AR needs HTTPS (or localhost).';
  if (!('xr' in navigator) || !navigator.xr) return 'No WebXR in this browser.';
  try {
    const ok = await navigator.xr.isSessionSupported('immersive-ar');
    return ok ? '' : 'AR is not supported on this browser or device.';
  } catch (e) {
    return `AR is not available (${(e && e.message) || e}).`;
  }
}

// Offers AR placement on `button` (its state in `note`) where the browser
// has it: the session's DOM overlay is `overlay`; `motion` (analyseMotion's)
// puts the feet on the floor; onPlaced() after a placement,
// onSessionChange(active) when the session starts or ends.
export async function setupAr({ stage, button, note, overlay, motion, onSessionChange, onPlaced }) {
  const reason = await arUnavailableReason();
  if (reason) {
    button.disabled = true;
    note.textContent = reason;
    button.title = reason;
    return;
  }
  button.disabled = false;
  note.textContent = '';
  const ar = new ArPlacement({ stage, button, note, overlay, motion, onSessionChange, onPlaced });
  button.addEventListener('click', () => ar.toggle());
}

// A ring on the floor where a tap would place the teacher.
function createReticle() {
  const reticle = new Mesh(
    new RingGeometry(0.12, 0.16, 40).rotateX(-Math.PI / 2),
    new MeshBasicMaterial({ color: 0x4fd1c5 }),
  );
  reticle.matrixAutoUpdate = false;
  reticle.visible = false;
  return reticle;
}

class ArPlacement {
  constructor({ stage, button, note, overlay, motion, onSessionChange, onPlaced }) {
    Object.assign(this, { stage, button, note, overlay, motion, onSessionChange, onPlaced });
    this.renderer = stage.renderer;
    this.renderer.xr.enabled = true;
    this.reticle = createReticle();
    stage.scene.add(this.reticle);
    this.session = null;
    this.hitSource = null;
    this.saved = { background: null, position: new Vector3(), yaw: 0 };
    this.hitPosition = new Vector3();
    // Taps on the controls are not placements.
    overlay.addEventListener('beforexrselect', (e) => {
      if (e.target.closest('button, input, select, label, a, .hud')) e.preventDefault();
    });
    const previousOnFrame = stage.onFrame;
    stage.onFrame = (dt, xrFrame) => {
      if (previousOnFrame) previousOnFrame(dt, xrFrame);
      this.followFloor(xrFrame);
    };
  }

  toggle() {
    if (this.session) this.session.end();
    else this.start();
  }

  async start() {
    const { stage, renderer, note } = this;
    let session;
    try {
      session = await navigator.xr.requestSession('immersive-ar', {
        requiredFeatures: ['hit-test'],
        optionalFeatures: ['dom-overlay', 'local-floor'],
        domOverlay: { root: this.overlay },
      });
    } catch (e) {
      note.textContent = `AR could not start: ${(e && e.message) || e}`;
      return;
    }
    this.session = session;
    this.saved.background = stage.scene.background;
    this.saved.position.copy(stage.placement.position);
    this.saved.yaw = stage.placement.rotation.y;
    stage.scene.background = null;
    stage.placement.visible = false;
    renderer.xr.setReferenceSpaceType('local');
    await renderer.xr.setSession(session);
    const viewerSpace = await session.requestReferenceSpace('viewer');
    this.hitSource = await session.requestHitTestSource({ space: viewerSpace });
    session.addEventListener('select', () => this.place());
    session.addEventListener('end', () => this.end());
    this.button.textContent = 'Exit AR';
    note.textContent = 'Point at the floor, then tap to place the teacher.';
    this.onSessionChange(true);
  }

  // A tap: the pivot (actor's mean, on the floor) goes to the hit.
  place() {
    const { stage, reticle } = this;
    if (!reticle.visible) return;
    this.hitPosition.setFromMatrixPosition(reticle.matrix);
    stage.placement.position.set(
      this.hitPosition.x - stage.pivot.x,
      this.hitPosition.y - this.motion.floorY,
      this.hitPosition.z - stage.pivot.z,
    );
    stage.placement.visible = true;
    // Turned to face whoever placed it.
    if (this.onPlaced) this.onPlaced();
    this.note.textContent = 'Placed. Tap elsewhere on the floor to move the teacher.';
  }

  end() {
    const { stage, saved } = this;
    if (this.hitSource) this.hitSource.cancel();
    this.hitSource = null;
    this.session = null;
    this.reticle.visible = false;
    stage.scene.background = saved.background;
    stage.placement.position.copy(saved.position);
    stage.placement.rotation.y = saved.yaw;
    stage.placement.visible = true;
    this.button.textContent = 'Place (AR)';
    this.note.textContent = '';
    this.onSessionChange(false);
    stage.invalidate();
  }

  // Each XR frame: the ring on the floor under the screen's centre.
  followFloor(xrFrame) {
    if (!xrFrame || !this.hitSource) return;
    const space = this.renderer.xr.getReferenceSpace();
    const hits = xrFrame.getHitTestResults(this.hitSource);
    if (hits.length > 0) {
      const pose = hits[0].getPose(space);
      this.reticle.visible = true;
      this.reticle.matrix.fromArray(pose.transform.matrix);
    } else {
      this.reticle.visible = false;
    }
  }
}
