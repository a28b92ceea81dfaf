// Numeric assertions with stated tolerances, for the unit tests in test/.

import assert from 'node:assert/strict';

// Asserts |actual - expected| <= tolerance (in the quantity's own units).
export function assertNear(actual, expected, tolerance, what = 'value') {
  assert.ok(
    Number.isFinite(actual) && Math.abs(actual - expected) <= tolerance,
    `${what}: ${actual} is not within ${tolerance} of ${expected}`,
  );
}

// Asserts each component of {x, y, z} `actual` within `tolerance` of
// `expected`.
export function assertNearVector(actual, expected, tolerance, what = 'vector') {
  for (const k of ['x', 'y', 'z']) assertNear(actual[k], expected[k], tolerance, `${what}.${k}`);
}
