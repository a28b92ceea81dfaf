"""The body tracker's network: its crop of a person's depth, its layers, and
how its output maps become joints.

The C++ tracker (common/tracking/pose_net.{h,cc}) implements the same crop
and decoding; the constants below must equal those in pose_net.h.

A person's depth is cut to a square of CROP_M metres round the mean pixel of
the person, at the median depth of the person, and sampled to IN x IN
(nearest pixel, no interpolation across depth edges). Each value is the
depth relative to the median over DEPTH_RANGE_M, clamped to [-1, 1]; off the
person (or without a measurement) it is 1.

The network is a small encoder-decoder (strides 2 to 16 and back to 4). For
every joint it gives a heat map and a depth map on the OUT x OUT grid; the
joint's crop coordinates are the expectation under the heat map's softmax
(integral regression: Sun et al., "Integral Human Pose Regression", ECCV
2018) and its depth is the depth map averaged with the same weights.
"""
import numpy as np
import torch
import torch.nn as nn

CROP_M = 2.4
DEPTH_RANGE_M = 1.2
IN = 96
OUT = 24
JOINTS = 25
MIN_PIXELS = 50
# Output z is (z - median) / Z_SCALE_M, so that one unit is as many metres
# as one unit of the crop's u and v.
Z_SCALE_M = CROP_M

# Kinect v2 joint order (body::KinectV2Joint).
JOINT_NAMES = [
    'SpineBase', 'SpineMid', 'Neck', 'Head', 'ShoulderLeft', 'ElbowLeft', 'WristLeft',
    'HandLeft', 'ShoulderRight', 'ElbowRight', 'WristRight', 'HandRight', 'HipLeft',
    'KneeLeft', 'AnkleLeft', 'FootLeft', 'HipRight', 'KneeRight', 'AnkleRight', 'FootRight',
    'SpineShoulder', 'HandTipLeft', 'ThumbLeft', 'HandTipRight', 'ThumbRight'
]
# The 20 body joints that evaluations score: the Kinect v1 skeleton's (hand
# tips, thumbs and the neck left out; SpineShoulder is Kinect v1's
# ShoulderCenter).
BODY_JOINTS = [j for j in range(21) if j != 2]
# The joint each one becomes in a mirror image.
_SWAP = {'Left': 'Right', 'Right': 'Left'}


def _mirror_name(name):
    for a, b in _SWAP.items():
        if name.endswith(a):
            return name[:-len(a)] + b
    return name


MIRROR = [JOINT_NAMES.index(_mirror_name(n)) for n in JOINT_NAMES]


def crop_params(depth_mm, fx, fy):
    """(uc, vc, zc, w, h) of the person (non-zero pixels), or None."""
    ys, xs = np.nonzero(depth_mm)
    if len(xs) < MIN_PIXELS:
        return None
    z = depth_mm[ys, xs]
    n = len(z)
    zc = float(np.partition(z, n // 2)[n // 2]) * 0.001
    uc = float(xs.astype(np.float64).sum() / n)
    vc = float(ys.astype(np.float64).sum() / n)
    return uc, vc, zc, CROP_M * fx / zc, CROP_M * fy / zc


def make_input(depth_mm, x0, y0, p):
    """The IN x IN input of `depth_mm` (a cut whose pixel (0, 0) is the
    image's (x0, y0)) for crop parameters p."""
    uc, vc, zc, w, h = p
    g = (np.arange(IN) + 0.5) / IN - 0.5
    xs = np.floor(uc + g * w + 0.5).astype(np.int64) - x0
    ys = np.floor(vc + g * h + 0.5).astype(np.int64) - y0
    H, W = depth_mm.shape
    okx = (xs >= 0) & (xs < W)
    oky = (ys >= 0) & (ys < H)
    d = depth_mm[np.clip(ys, 0, H - 1)[:, None], np.clip(xs, 0, W - 1)[None, :]]
    d = np.where(oky[:, None] & okx[None, :], d, 0)
    v = np.clip((d * 0.001 - zc) / DEPTH_RANGE_M, -1.0, 1.0)
    return np.where(d > 0, v, 1.0).astype(np.float32)


def joints_to_targets(joints_m, K, p):
    """Joints (N, 3) in the camera frame -> (N, 3) of crop u, v in [0, 1]
    and z relative to the median over Z_SCALE_M."""
    fx, fy, cx, cy = K
    uc, vc, zc, w, h = p
    z = np.where(joints_m[:, 2] > 0, joints_m[:, 2], 1.0)
    u = fx * joints_m[:, 0] / z + cx
    v = fy * joints_m[:, 1] / z + cy
    return np.stack([(u - uc) / w + 0.5, (v - vc) / h + 0.5, (z - zc) / Z_SCALE_M], axis=1)


def targets_to_joints(t, K, p):
    """Inverse of joints_to_targets (pinhole)."""
    fx, fy, cx, cy = K
    uc, vc, zc, w, h = p
    u = uc + (t[..., 0] - 0.5) * w
    v = vc + (t[..., 1] - 0.5) * h
    z = zc + t[..., 2] * Z_SCALE_M
    return np.stack([(u - cx) * z / fx, (v - cy) * z / fy, z], axis=-1)


def _cbr(i, o, stride=1, k=3):
    return nn.Sequential(nn.Conv2d(i, o, k, stride, k // 2, bias=False), nn.BatchNorm2d(o),
                         nn.ReLU(inplace=True))


class PoseNet(nn.Module):
    """IN x IN depth -> 2 * JOINTS maps of OUT x OUT: heat-map logits, then
    depth maps."""

    def __init__(self, joints=JOINTS):
        super().__init__()
        self.s1 = nn.Sequential(_cbr(1, 16, 2), _cbr(16, 24))  # 48
        self.s2 = nn.Sequential(_cbr(24, 48, 2), _cbr(48, 48))  # 24
        self.s3 = nn.Sequential(_cbr(48, 96, 2), _cbr(96, 96))  # 12
        self.s4 = nn.Sequential(_cbr(96, 160, 2), _cbr(160, 160), _cbr(160, 160))  # 6
        self.l4 = _cbr(160, 96, 1, 1)
        self.u3 = _cbr(96, 96)
        self.l3 = _cbr(96, 48, 1, 1)
        self.u2 = _cbr(48, 48)
        self.up = nn.Upsample(scale_factor=2, mode='nearest')
        self.head = nn.Conv2d(48, 2 * joints, 1)
        self.joints = joints

    def forward(self, x):
        a = self.s1(x)
        b = self.s2(a)
        c = self.s3(b)
        d = self.s4(c)
        c2 = self.u3(self.up(self.l4(d)) + c)
        b2 = self.u2(self.up(self.l3(c2)) + b)
        return self.head(b2)


def decode(maps):
    """(B, 2J, OUT, OUT) maps -> (B, J, 3) crop targets (integral regression)."""
    b, c, hgt, wid = maps.shape
    j = c // 2
    logits = maps[:, :j].reshape(b, j, hgt * wid)
    prob = torch.softmax(logits, dim=2).reshape(b, j, hgt, wid)
    depth = maps[:, j:]
    gx = (torch.arange(wid, dtype=maps.dtype) + 0.5) / wid
    gy = (torch.arange(hgt, dtype=maps.dtype) + 0.5) / hgt
    u = (prob.sum(dim=2) * gx).sum(dim=2)
    v = (prob.sum(dim=3) * gy).sum(dim=2)
    z = (prob * depth).sum(dim=(2, 3))
    return torch.stack([u, v, z], dim=2)
