import assert from 'node:assert/strict';
import { test } from 'node:test';
import {
  faceCameraYawDeg,
  framingOf,
  orbitDegPerPx,
  orbitRotateSpeed,
  roundMicro,
  verticalFovDeg,
  wrapYawDeg,
} from '../src/lib/geometry.js';
import { assertNear, assertNearVector } from '../testing/near.mjs';

const DEG = Math.PI / 180;

test('verticalFovDeg: equal for a square view, narrower for a wide one', () => {
  assertNear(verticalFovDeg(50, 1), 50, 1e-9, 'vfov (deg)');
  assertNear(verticalFovDeg(90, 2), 53.130102354, 1e-6, 'vfov (deg)');
  assertNear(verticalFovDeg(50, 16 / 9), 29.394957604, 1e-6, 'vfov (deg)');
});

// The corners of box {min, max}.
function corners({ min, max }) {
  const out = [];
  for (const x of [min.x, max.x]) for (const y of [min.y, max.y]) for (const z of [min.z, max.z]) out.push({ x, y, z });
  return out;
}

const sub = (a, b) => ({ x: a.x - b.x, y: a.y - b.y, z: a.z - b.z });
const dot = (a, b) => a.x * b.x + a.y * b.y + a.z * b.z;
const cross = (a, b) => ({ x: a.y * b.z - a.z * b.y, y: a.z * b.x - a.x * b.z, z: a.x * b.y - a.y * b.x });
const unit = (a) => {
  const n = Math.sqrt(dot(a, a));
  return { x: a.x / n, y: a.y / n, z: a.z / n };
};

// The largest |x| / tan(hfov/2) and |y| / tan(vfov/2) of the box's corners
// in a pinhole camera at `eye` looking at `target` (+Y up): 1 at the view's
// edge.
function fillOfView(box, { eye, target }, hfovDeg, aspect) {
  const forward = unit(sub(target, eye));
  const right = unit(cross(forward, { x: 0, y: 1, z: 0 }));
  const up = cross(right, forward);
  const tanH = Math.tan((hfovDeg / 2) * DEG);
  const tanV = Math.tan((verticalFovDeg(hfovDeg, aspect) / 2) * DEG);
  let fillX = 0;
  let fillY = 0;
  for (const p of corners(box)) {
    const d = sub(p, eye);
    const depth = dot(d, forward);
    assert.ok(depth > 0, 'every corner is in front of the camera');
    fillX = Math.max(fillX, Math.abs(dot(d, right) / depth) / tanH);
    fillY = Math.max(fillY, Math.abs(dot(d, up) / depth) / tanV);
  }
  return { fillX, fillY };
}

test('framingOf looks at the mean at mid-height, from in front along the facing and above', () => {
  const extent = { min: { x: -0.3, y: 0, z: -0.2 }, max: { x: 0.3, y: 1.8, z: 0.2 } };
  const view = framingOf(extent, { x: 0.1, y: 0.9, z: -0.05 }, { x: 0, y: 0, z: 1 }, 50, 4 / 3);
  assertNearVector(view.target, { x: 0.1, y: 0.9, z: -0.05 }, 1e-12, 'target (m)');
  assertNear(view.eye.x, 0.1, 1e-12, 'eye.x (m)');
  const distance = view.eye.z - view.target.z;
  assert.ok(distance > 1 && distance < 10, `distance ${distance} m`);
  assertNear(view.eye.y - view.target.y, 0.12 * distance, 1e-12, 'eye height above the target (m)');
});

test('framingOf fits the whole box in view with a margin, filling most of it', () => {
  const extent = { min: { x: -0.4, y: 0, z: -0.3 }, max: { x: 0.5, y: 1.75, z: 0.6 } };
  const mean = { x: 0.05, y: 0.9, z: 0.1 };
  for (const [facing, aspect] of [
    [{ x: 0, y: 0, z: 1 }, 16 / 9],
    [{ x: 1, y: 0, z: 0 }, 3 / 4],
    [unit({ x: 1, y: 0, z: -1 }), 1],
  ]) {
    const { fillX, fillY } = fillOfView(extent, framingOf(extent, mean, facing, 50, aspect), 50, aspect);
    assert.ok(fillX < 1 && fillY < 1, `the box overflows the view: ${fillX}, ${fillY} at aspect ${aspect}`);
    assert.ok(Math.max(fillX, fillY) > 0.6, `the box is lost in the view: ${fillX}, ${fillY} at aspect ${aspect}`);
  }
});

test('framingOf of an empty box looks at the mean at y = 0 from 0.05 m margins', () => {
  const empty = { min: { x: Infinity, y: Infinity, z: Infinity }, max: { x: -Infinity, y: -Infinity, z: -Infinity } };
  const view = framingOf(empty, { x: 1, y: 5, z: 2 }, { x: 0, y: 0, z: 1 }, 90, 1);
  assertNearVector(view.target, { x: 1, y: 0, z: 2 }, 1e-12, 'target (m)');
  // Half-extent 0.05 m at tan(45 deg) = 1: 0.05 m away.
  assertNearVector(view.eye, { x: 1, y: 0.006, z: 2.05 }, 1e-12, 'eye (m)');
});

test('orbitDegPerPx turns about 180 degrees across the view, within 0.2-0.4 degrees a pixel', () => {
  assertNear(orbitDegPerPx(600), 0.3, 1e-12, 'deg/px at 600 px');
  assert.equal(orbitDegPerPx(1280), 0.2);
  assert.equal(orbitDegPerPx(320), 0.4);
  assert.equal(orbitDegPerPx(0), 0.4);
  // OrbitControls turns 2 pi x rotateSpeed / height radians a pixel.
  const speed = orbitRotateSpeed(600, 720);
  assertNear((2 * Math.PI * speed) / 720 / DEG, 0.3, 1e-12, 'deg/px through OrbitControls');
});

test('wrapYawDeg wraps into [-180, 180) and never gives -0', () => {
  assert.equal(wrapYawDeg(190), -170);
  assert.equal(wrapYawDeg(-190), 170);
  assert.equal(wrapYawDeg(180), -180);
  assert.equal(wrapYawDeg(-180), -180);
  assert.equal(wrapYawDeg(720 + 45), 45);
  assert.ok(Object.is(wrapYawDeg(-0), 0));
  assert.ok(Object.is(wrapYawDeg(360), 0));
});

test('faceCameraYawDeg turns the facing onto the camera, less the placement turn', () => {
  assertNear(faceCameraYawDeg({ x: 0, z: 1 }, { x: 0, z: 1 }, 0), 0, 1e-12, 'yaw (deg)');
  assertNear(faceCameraYawDeg({ x: 1, z: 0 }, { x: 0, z: 1 }, 0), 90, 1e-12, 'yaw (deg)');
  assertNear(faceCameraYawDeg({ x: 0, z: 1 }, { x: 1, z: 0 }, 0), -90, 1e-12, 'yaw (deg)');
  assertNear(faceCameraYawDeg({ x: 1, z: 0 }, { x: 0, z: 1 }, 30 * DEG), 60, 1e-12, 'yaw (deg)');
});

test('roundMicro rounds to a millionth', () => {
  assert.equal(roundMicro(1.23456789), 1.234568);
  assert.equal(roundMicro(-0.0000004), -0);
});
