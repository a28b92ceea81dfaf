// The camera's geometry: fields of view, the framing of the actor's
// bounding box, the orbit's rate and the teacher's turn. Angles in degrees
// unless named _rad; lengths in metres; points and vectors as {x, y, z}.

const DEG2RAD = Math.PI / 180;
const RAD2DEG = 180 / Math.PI;

// Orbiting: degrees the view turns per pixel dragged. A drag across the
// whole canvas turns about 180 degrees, within these bounds (a phone's
// narrow screen still turns gently, a wide one not sluggishly).
export const ORBIT_DEG_PER_PX_MIN = 0.2;
export const ORBIT_DEG_PER_PX_MAX = 0.4;

// The vertical field of view of a pinhole camera with horizontal field of
// view `hfovDeg` and aspect ratio `aspect` (width / height).
export function verticalFovDeg(hfovDeg, aspect) {
  const h = hfovDeg * DEG2RAD;
  return RAD2DEG * (2 * Math.atan(Math.tan(h / 2) / aspect));
}

// Whether a box {min, max} holds no point (as three.js's Box3.isEmpty).
function boxIsEmpty({ min, max }) {
  return max.x < min.x || max.y < min.y || max.z < min.z;
}

// A box's size and centre; zero for an empty box.
function boxSizeAndCentre(box) {
  if (boxIsEmpty(box)) return { size: { x: 0, y: 0, z: 0 }, centre: { x: 0, y: 0, z: 0 } };
  const { min, max } = box;
  return {
    size: { x: max.x - min.x, y: max.y - min.y, z: max.z - min.z },
    centre: { x: (min.x + max.x) * 0.5, y: (min.y + max.y) * 0.5, z: (min.z + max.z) * 0.5 },
  };
}

// A camera in front of the actor (along `facing`, a horizontal unit
// vector, and slightly above), looking at its `mean` position at the
// mid-height of `extent` (its bounding box {min, max} over the whole
// motion) and framing that box, with a margin, in a view `hfovDeg` wide of
// aspect `aspect`. {eye, target}.
export function framingOf(extent, mean, facing, hfovDeg, aspect) {
  const { size, centre } = boxSizeAndCentre(extent);
  const target = { x: mean.x, y: centre.y, z: mean.z };
  const hfov = hfovDeg * DEG2RAD;
  const vfov = verticalFovDeg(hfovDeg, aspect) * DEG2RAD;
  const depth = Math.max(size.x, size.z);
  const halfWidth = 0.5 * depth * 1.15 + 0.05;
  const halfHeight = 0.5 * size.y * 1.12 + 0.05;
  const distance = Math.max(halfWidth / Math.tan(hfov / 2), halfHeight / Math.tan(vfov / 2)) + 0.5 * depth;
  const eye = {
    x: target.x + facing.x * distance,
    y: target.y + facing.y * distance + 0.12 * distance,
    z: target.z + facing.z * distance,
  };
  return { eye, target };
}

// Degrees turned per pixel dragged on a canvas `width` pixels wide.
export function orbitDegPerPx(width) {
  return Math.max(ORBIT_DEG_PER_PX_MIN, Math.min(ORBIT_DEG_PER_PX_MAX, 180 / Math.max(1, width)));
}

// OrbitControls turns 2 pi x rotateSpeed / (the canvas height) radians per
// pixel: the rotateSpeed that turns orbitDegPerPx(width) degrees.
export function orbitRotateSpeed(width, height) {
  return (orbitDegPerPx(width) * Math.max(1, height)) / 360;
}

// A turn `deg` wrapped into [-180, 180) (never -0).
export function wrapYawDeg(deg) {
  let d = ((((deg + 180) % 360) + 360) % 360) - 180;
  if (Object.is(d, -0)) d = 0;
  return d;
}

// The turn (degrees) that makes an actor facing `facing` look along
// `toCamera` (both horizontal directions {x, z}), on a placement already
// turned by `placementYawRad` about the vertical.
export function faceCameraYawDeg(toCamera, facing, placementYawRad) {
  const wanted = Math.atan2(toCamera.x, toCamera.z);
  const current = Math.atan2(facing.x, facing.z);
  return (wanted - current - placementYawRad) * RAD2DEG;
}

// The camera's pose for reenactCamera(): numbers rounded to 1e-6.
export function roundMicro(x) {
  return Math.round(x * 1e6) / 1e6;
}
