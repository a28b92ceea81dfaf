// AR placement (WebXR immersive-ar with hit-test and dom-overlay): a ring
// follows the floor under the screen's centre; a tap puts the teacher there
// at real scale, feet on the floor. The page's controls stay usable in the
// overlay.

import { Mesh, MeshBasicMaterial, RingGeometry, Matrix4, Quaternion, Vector3 } from 'three';

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

  const renderer = stage.renderer;
  renderer.xr.enabled = true;
  const reticle = new Mesh(
    new RingGeometry(0.12, 0.16, 40).rotateX(-Math.PI / 2),
    new MeshBasicMaterial({ color: 0x4fd1c5 }),
  );
  reticle.matrixAutoUpdate = false;
  reticle.visible = false;
  stage.scene.add(reticle);

  let session = null;
  let hitSource = null;
  const saved = { background: null, position: new Vector3(), yaw: 0 };
  const hitMatrix = new Matrix4();
  const hitPosition = new Vector3();
  const hitQuaternion = new Quaternion();
  const hitScale = new Vector3();

  // Taps on the controls are not placements.
  overlay.addEventListener('beforexrselect', (e) => {
    if (e.target.closest('button, input, select, label, a, .hud')) e.preventDefault();
  });

  async function start() {
    try {
      session = await navigator.xr.requestSession('immersive-ar', {
        requiredFeatures: ['hit-test'],
        optionalFeatures: ['dom-overlay', 'local-floor'],
        domOverlay: { root: overlay },
      });
    } catch (e) {
      note.textContent = `AR could not start: ${(e && e.message) || e}`;
      return;
    }
    saved.background = stage.scene.background;
    saved.position.copy(stage.placement.position);
    saved.yaw = stage.placement.rotation.y;
    stage.scene.background = null;
    stage.placement.visible = false;
    renderer.xr.setReferenceSpaceType('local');
    await renderer.xr.setSession(session);
    const viewerSpace = await session.requestReferenceSpace('viewer');
    hitSource = await session.requestHitTestSource({ space: viewerSpace });
    session.addEventListener('select', onSelect);
    session.addEventListener('end', onEnd);
    button.textContent = 'Exit AR';
    note.textContent = 'Point at the floor, then tap to place the teacher.';
    onSessionChange(true);
  }

  function onSelect() {
    if (!reticle.visible) return;
    hitMatrix.copy(reticle.matrix);
    hitMatrix.decompose(hitPosition, hitQuaternion, hitScale);
    // The pivot (actor's mean, on the floor) goes to the hit.
    stage.placement.position.set(
      hitPosition.x - stage.pivot.x,
      hitPosition.y - motion.floorY,
      hitPosition.z - stage.pivot.z,
    );
    stage.placement.visible = true;
    // Turned to face whoever placed it.
    if (onPlaced) onPlaced();
    note.textContent = 'Placed. Tap elsewhere on the floor to move the teacher.';
  }

  function onEnd() {
    if (hitSource) hitSource.cancel();
    hitSource = null;
    session = null;
    reticle.visible = false;
    stage.scene.background = saved.background;
    stage.placement.position.copy(saved.position);
    stage.placement.rotation.y = saved.yaw;
    stage.placement.visible = true;
    button.textContent = 'Place (AR)';
    note.textContent = '';
    onSessionChange(false);
    stage.invalidate();
  }

  const previousOnFrame = stage.onFrame;
  stage.onFrame = (dt, xrFrame) => {
    if (previousOnFrame) previousOnFrame(dt, xrFrame);
    if (!xrFrame || !hitSource) return;
    const space = renderer.xr.getReferenceSpace();
    const hits = xrFrame.getHitTestResults(hitSource);
    if (hits.length > 0) {
      const pose = hits[0].getPose(space);
      reticle.visible = true;
      reticle.matrix.fromArray(pose.transform.matrix);
    } else {
      reticle.visible = false;
    }
  };

  button.addEventListener('click', () => {
    if (session) session.end();
    else start();
  });
}
