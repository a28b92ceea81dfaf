#!/usr/bin/env python3
"""Trains the body tracker's network (pose_net.py) and writes it as ONNX.

Reads folders laid out like ../shared/data/rgbd-seq (frames/NNNN.png in mm,
meta.json with intrinsics, joint names and joints_m per frame; a frame may
carry its own "intrinsics"), from real recordings with the Kinect SDK's
skeleton and from `reenact tracker synth` (the project's own renders with
their true joints). Subjects named by --val are never trained on: they
measure the network after every --eval-every steps.

  python3 models/tracker/train_pose_net.py --real ../shared/data/rgbd-seq \\
      --synthetic /tmp/synth --out models/tracker/pose_net.onnx --seed 1

needs python3-torch, python3-onnx, python3-numpy and python3-opencv (Debian 12).
"""
import argparse
import copy
import json
import math
import os
import sys
import time

import cv2
import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import pose_net as pn  # noqa: E402

V1_TO_V2 = {'ShoulderCenter': 'SpineShoulder', 'Spine': 'SpineMid', 'HipCenter': 'SpineBase'}


class Frames:
    """Cut person depth, crop parameters, intrinsics, joints and joint weights."""

    def __init__(self):
        self.cuts, self.origin, self.params, self.K = [], [], [], []
        self.joints, self.weights, self.seq, self.index = [], [], [], []

    def __len__(self):
        return len(self.cuts)


def read_folder(folder, frames, frame_step=1, weight_extremities=0.5):
    meta = json.load(open(os.path.join(folder, 'meta.json')))
    names = [V1_TO_V2.get(n, n) for n in meta.get('joint_names', pn.JOINT_NAMES)]
    K0 = meta.get('intrinsics')
    name = os.path.basename(folder.rstrip('/'))
    for i, f in enumerate(meta['frames']):
        if i % frame_step:
            continue
        K = f.get('intrinsics', K0)
        depth = cv2.imread(os.path.join(folder, f['depth']), cv2.IMREAD_ANYDEPTH)
        if depth is None or depth.dtype != np.uint16:
            raise SystemExit(f'{folder}: {f["depth"]} is not a 16-bit PNG')
        p = pn.crop_params(depth, K[0], K[1])
        if p is None:
            continue
        ys, xs = np.nonzero(depth)
        x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
        joints = np.zeros((pn.JOINTS, 3), np.float32)
        weights = np.zeros(pn.JOINTS, np.float32)
        jm = f['joints_m']
        if isinstance(jm, dict):
            pairs = [(V1_TO_V2.get(n, n), v) for n, v in jm.items()]
        else:
            pairs = list(zip(names, jm))
        for n, v in pairs:
            if n not in pn.JOINT_NAMES or v is None:
                continue
            j = pn.JOINT_NAMES.index(n)
            v = np.asarray(v, np.float64)
            if v.shape == (3,) and np.all(np.isfinite(v)) and v[2] > 0.1:
                joints[j] = v
                weights[j] = weight_extremities if j >= 21 else 1.0
        frames.cuts.append(depth[y0:y1, x0:x1].copy())
        frames.origin.append((int(x0), int(y0)))
        frames.params.append(p)
        frames.K.append(tuple(K))
        frames.joints.append(joints)
        frames.weights.append(weights)
        frames.seq.append(name)
        frames.index.append(i)


def subject_of(name):
    # utd-kinect2-a01-s3-t1 -> ('kinect2', 3); utd-mhad-... -> ('mhad', s)
    parts = name.split('-')
    return parts[1], int(parts[3][1:])


def parse_subjects(text):
    """'kinect2:1,2;mhad:1,2,3' -> {('kinect2', 1), ...}"""
    out = set()
    for group in filter(None, text.split(';')):
        ds, subs = group.split(':')
        out |= {(ds, int(s)) for s in subs.split(',')}
    return out


def sample(frames, i, rng, augment):
    p = frames.params[i]
    K = frames.K[i]
    if augment:
        uc, vc, zc, w, h = p
        s = math.exp(rng.uniform(-0.12, 0.12))
        p = (uc + rng.uniform(-0.05, 0.05) * w, vc + rng.uniform(-0.05, 0.05) * h, zc, w * s, h * s)
    x0, y0 = frames.origin[i]
    inp = pn.make_input(frames.cuts[i], x0, y0, p)
    t = pn.joints_to_targets(frames.joints[i].astype(np.float64), K, p).astype(np.float32)
    w = frames.weights[i].copy()
    t[w == 0] = 0
    if augment:
        person = inp < 1.0
        if rng.random() < 0.7:  # Depth noise beyond the sensor's.
            inp = np.where(person, inp + rng.normal(0, rng.uniform(0, 0.012), inp.shape), inp)
        for _ in range(rng.integers(0, 4)):  # Holes and lost pixels.
            a, b = rng.integers(0, pn.IN, 2)
            r = rng.integers(1, 8)
            inp[max(0, a - r):a + r, max(0, b - r):b + r] = 1.0
        if rng.random() < 0.15:  # Something in front of part of the person.
            a, b = rng.integers(0, pn.IN, 2)
            r = rng.integers(4, 16)
            patch = inp[max(0, a - r):a + r, max(0, b - r):b + r]
            patch[patch < 1.0] -= rng.uniform(0.1, 0.4)
        if rng.random() < 0.3:  # Stray floor or background pixels under the feet.
            a = rng.integers(pn.IN * 3 // 4, pn.IN)
            row = inp[a]
            near = rng.random(pn.IN) < 0.3
            row[near] = np.clip(rng.uniform(-0.3, 0.5), -1, 1)
        inp = np.clip(inp, -1.0, 1.0).astype(np.float32)
        if rng.random() < 0.5:  # Mirror: left and right swap.
            inp = inp[:, ::-1].copy()
            t[:, 0] = np.where(w > 0, 1.0 - t[:, 0], 0)
            t = t[pn.MIRROR]
            w = w[pn.MIRROR]
    return inp, t, w


def batch(frames, ids, rng, augment):
    xs, ts, ws = zip(*(sample(frames, i, rng, augment) for i in ids))
    return (torch.from_numpy(np.stack(xs)[:, None]), torch.from_numpy(np.stack(ts)),
            torch.from_numpy(np.stack(ws)))


def loss_fn(pred, t, w):
    # Units of the crop (1 = CROP_M metres in u, v and z), so the loss is
    # close to a mean joint error over CROP_M.
    err = (pred - t).abs().sum(dim=2)
    return (err * w).sum() / w.sum().clamp(min=1)


def evaluate(model, frames, bs=128):
    model.eval()
    errs, swaps = [], []
    with torch.no_grad():
        for s in range(0, len(frames), bs):
            ids = list(range(s, min(len(frames), s + bs)))
            x, _, _ = batch(frames, ids, None, False)
            pred = pn.decode(model(x)).numpy().astype(np.float64)
            for k, i in enumerate(ids):
                j = pn.targets_to_joints(pred[k], frames.K[i], frames.params[i])
                m = frames.weights[i][pn.BODY_JOINTS] > 0
                d = np.linalg.norm(j[pn.BODY_JOINTS] - frames.joints[i][pn.BODY_JOINTS], axis=1)
                errs.append(d[m])
    model.train()
    e = np.concatenate(errs) if errs else np.zeros(1)
    return 1000 * e.mean(), 100 * (e < 0.1).mean()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--real', default='', help='a folder of rgbd-seq-like sequences')
    ap.add_argument('--train', default='kinect2:1,2;mhad:1,2,3', help='real subjects to train on')
    ap.add_argument('--val', default='kinect2:3;mhad:4', help='real subjects to validate on')
    ap.add_argument('--synthetic', default='', help='folders of `reenact tracker synth`, comma-separated')
    ap.add_argument('--synthetic-val', default='',
                    help='a folder of `reenact tracker synth --held-out`, reported, never trained on')
    ap.add_argument('--out', default='models/tracker/pose_net.onnx')
    ap.add_argument('--steps', type=int, default=6000)
    ap.add_argument('--batch', type=int, default=32)
    ap.add_argument('--lr', type=float, default=2e-3)
    ap.add_argument('--real-share', type=float, default=0.5)
    ap.add_argument('--eval-every', type=int, default=500)
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--ema', type=float, default=0.998)
    ap.add_argument('--seed', type=int, default=1)
    args = ap.parse_args()

    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    torch.set_num_threads(args.threads)
    start = time.time()

    real_train, real_val, synth, synth_val = Frames(), Frames(), Frames(), Frames()
    train_subjects, val_subjects = parse_subjects(args.train), parse_subjects(args.val)
    if args.real:
        for name in sorted(os.listdir(args.real)):
            folder = os.path.join(args.real, name)
            if not os.path.isfile(os.path.join(folder, 'meta.json')):
                continue
            sub = subject_of(name)
            if sub in train_subjects:
                read_folder(folder, real_train)
            elif sub in val_subjects:
                read_folder(folder, real_val, frame_step=2)
    for folder in filter(None, args.synthetic.split(',')):
        read_folder(folder, synth, weight_extremities=1.0)
    if args.synthetic_val:
        read_folder(args.synthetic_val, synth_val, weight_extremities=1.0)
    print(f'frames: real train {len(real_train)}, real val {len(real_val)}, synthetic {len(synth)}, '
          f'synthetic val {len(synth_val)}; '
          f'read in {time.time() - start:.0f} s', flush=True)
    if len(real_train) + len(synth) == 0:
        raise SystemExit('nothing to train on')

    model = pn.PoseNet()
    # The exported network is an exponential moving average of the weights
    # (decay --ema): single steps at a high learning rate move the held-out
    # error by tens of millimetres, the average does not.
    ema = copy.deepcopy(model)
    for p in ema.parameters():
        p.requires_grad_(False)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=args.steps,
                                                pct_start=0.05)
    n_real = int(round(args.batch * args.real_share)) if len(real_train) else 0
    if not len(synth):
        n_real = args.batch
    running = 0.0
    for step in range(1, args.steps + 1):
        xr = batch(real_train, rng.integers(0, len(real_train), n_real), rng, True) if n_real else None
        xs = batch(synth, rng.integers(0, len(synth), args.batch - n_real), rng, True) \
            if args.batch - n_real else None
        parts = [b for b in (xr, xs) if b is not None]
        x = torch.cat([b[0] for b in parts])
        t = torch.cat([b[1] for b in parts])
        w = torch.cat([b[2] for b in parts])
        loss = loss_fn(pn.decode(model(x)), t, w)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        with torch.no_grad():
            decay = min(args.ema, (1 + step) / (10 + step))
            for te, tm in zip(ema.state_dict().values(), model.state_dict().values()):
                if te.dtype.is_floating_point:
                    te.mul_(decay).add_(tm.detach(), alpha=1 - decay)
                else:
                    te.copy_(tm)
        running = 0.98 * running + 0.02 * loss.item() if step > 1 else loss.item()
        if step % args.eval_every == 0 or step == args.steps:
            msg = f'step {step}: loss {running * pn.CROP_M * 1000 / 3:.1f} mm/axis'
            if len(real_val):
                mpjpe, pck = evaluate(ema, real_val)
                msg += f', held-out real {mpjpe:.1f} mm, PCK@10cm {pck:.1f} %'
            if len(synth_val):
                mpjpe, pck = evaluate(ema, synth_val)
                msg += f', held-out synthetic {mpjpe:.1f} mm, PCK@10cm {pck:.1f} %'
            print(f'{msg} ({time.time() - start:.0f} s)', flush=True)

    model = ema
    model.eval()
    dummy = torch.zeros(1, 1, pn.IN, pn.IN)
    torch.onnx.export(model, dummy, args.out, opset_version=11, input_names=['depth'],
                      output_names=['maps'])
    inline_identities(args.out)
    print(f'wrote {args.out} ({os.path.getsize(args.out)} bytes) in {time.time() - start:.0f} s')


def inline_identities(path):
    """OpenCV 4.6's ONNX importer refuses Identity nodes, which the exporter
    makes for initializers that folded to the same values: give each its own
    copy."""
    import onnx
    m = onnx.load(path)
    inits = {i.name: i for i in m.graph.initializer}
    keep = []
    for n in m.graph.node:
        if n.op_type == 'Identity' and n.input[0] in inits:
            t = onnx.TensorProto()
            t.CopyFrom(inits[n.input[0]])
            t.name = n.output[0]
            m.graph.initializer.append(t)
        else:
            keep.append(n)
    del m.graph.node[:]
    m.graph.node.extend(keep)
    onnx.checker.check_model(m)
    onnx.save(m, path)


if __name__ == '__main__':
    main()
