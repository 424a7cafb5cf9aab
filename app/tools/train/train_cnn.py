#!/usr/bin/env python3
"""Trains the marking classifier's convolutional networks (marking_classifier.hpp).

Reads the candidates markloop-train writes with --dump DUMP (their
patches, shape features, labels and folds; train-model.sh makes
them), trains per seed (one network of the ensemble each) one network per
cross-validation fold (that fold's real clips held out) and one on
everything, and writes, S the seed:
  DUMP/cnn/seedS/train0.foldF.probs.f32  held-out class probabilities of fold F's
                              real candidates, summed into DUMP/cnn/seedS/train0.probs.f32
                              once every fold's is there (folds may run in parallel runs)
  DUMP/cnn/seedS/testK.probs.f32  the final network's, on the simulator test sets
  OUT (--out)                 the final networks, one per seed, as a model file
                              (app/perception/model/README.md; OUT.txt beside it:
                              how they were trained)
markloop-train --scores DUMP/mlp --scores DUMP/cnn/seed1 ... judges the
probabilities. Fixed seeds and thread count: the same inputs give the same
networks on one machine.
Needs python3-torch and python3-numpy (Debian packages: bash .ci/setup train).
"""
import argparse
import os
import sys
import time
import zlib

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "perception", "model"))
import model_file  # noqa: E402  (the model files' format, beside the model)

K = 17        # kClassifierOutputs
REJECT = 16   # kRejectClass
ROWS, COLS = 32, 16  # kPatchRows, kPatchCols
SHAPE = 6     # kShapeFeatures: the last features
C1, C2, C3, HIDDEN = 8, 16, 32, 64  # kCnnChannels1..3, kCnnHidden


def load(prefix):
    """One set's arrays, as markloop-train's dump_set() writes them."""
    meta = np.fromfile(prefix + ".meta.i32", dtype=np.int32).reshape(-1, 8)
    n = meta.shape[0]
    feats = np.fromfile(prefix + ".features.f32", dtype=np.float32)
    grey = np.fromfile(prefix + ".grey.f32", dtype=np.float32)
    paint = np.fromfile(prefix + ".paint.u8", dtype=np.uint8)
    if n == 0 or feats.size % n or grey.size != n * ROWS * COLS or paint.size != n * ROWS * COLS:
        sys.exit(f"train_cnn.py: {prefix}.*: sizes do not agree ({n} samples)")
    feats = feats.reshape(n, -1)
    image = np.concatenate([grey.reshape(n, 1, ROWS, COLS),
                            paint.reshape(n, 1, ROWS, COLS).astype(np.float32) / 255.0], 1)
    return meta, feats[:, -SHAPE:].copy(), image


def make_network(torch, dropout=0.0):
    nn = torch.nn

    class Cnn(nn.Module):
        def __init__(self):
            super().__init__()
            self.conv = nn.Sequential(
                nn.Conv2d(2, C1, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2),
                nn.Conv2d(C1, C2, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2),
                nn.Conv2d(C2, C3, 3, padding=1), nn.ReLU())
            self.fc1 = nn.Linear(C3 * (ROWS // 4) * (COLS // 4) + SHAPE, HIDDEN)
            self.fc2 = nn.Linear(HIDDEN, K)

        def forward(self, image, shape):
            x = torch.cat([self.conv(image).flatten(1), shape], 1)
            hidden = torch.nn.functional.dropout(torch.relu(self.fc1(x)), dropout, self.training)
            return self.fc2(hidden)

    return Cnn()


def cut_out(torch, image, probability, generator):
    """Random erasing: in a share of the patches, a random rectangle (up to
    half the patch each way) is set to the road's mean grey and to no paint,
    as a shadow, wear or an occluding object would hide part of a marking."""
    n = image.shape[0]
    rows = torch.arange(ROWS).view(1, ROWS, 1)
    cols = torch.arange(COLS).view(1, 1, COLS)
    height = torch.randint(2, ROWS // 2 + 1, (n, 1, 1), generator=generator)
    width = torch.randint(2, COLS // 2 + 1, (n, 1, 1), generator=generator)
    top = (torch.rand((n, 1, 1), generator=generator) * (ROWS - height + 1)).long()
    left = (torch.rand((n, 1, 1), generator=generator) * (COLS - width + 1)).long()
    chosen = torch.rand((n, 1, 1), generator=generator) < probability
    erase = chosen & (rows >= top) & (rows < top + height) & (cols >= left) & (cols < left + width)
    return image.masked_fill(erase.unsqueeze(1), 0.0)


def jitter(torch, image, generator):
    """Appearance and placement noise, one draw per patch: the patch moved by
    up to 2 pixels each way (edges repeated), its grey blurred in half the
    patches and given noise, then standardised again (zero mean, unit
    spread, as compute_features() gives it), its paint grown or shrunk by a
    pixel in a quarter each, as another camera, exposure, wear or paint
    threshold would change a marking. Tried and not adopted (docs/decisions.md)."""
    n = image.shape[0]
    f = torch.nn.functional
    padded = f.pad(image, (2, 2, 2, 2), mode="replicate")
    dy = torch.randint(0, 5, (n,), generator=generator)
    dx = torch.randint(0, 5, (n,), generator=generator)
    rows = (dy.view(n, 1, 1) + torch.arange(ROWS).view(1, ROWS, 1)).expand(n, ROWS, COLS)
    cols = (dx.view(n, 1, 1) + torch.arange(COLS).view(1, 1, COLS)).expand(n, ROWS, COLS)
    flat = (rows * (COLS + 4) + cols).view(n, 1, ROWS * COLS).expand(n, 2, ROWS * COLS)
    moved = padded.flatten(2).gather(2, flat).view(n, 2, ROWS, COLS)
    grey, paint = moved[:, :1], moved[:, 1:]
    blur = torch.rand((n, 1, 1, 1), generator=generator) < 0.5
    grey = torch.where(blur, f.avg_pool2d(f.pad(grey, (1, 1, 1, 1), mode="replicate"), 3, 1), grey)
    grey = grey + torch.randn(grey.shape, generator=generator) * (
        0.3 * torch.rand((n, 1, 1, 1), generator=generator))
    grey = (grey - grey.mean((2, 3), keepdim=True)) / (grey.std((2, 3), keepdim=True) + 1e-3)
    which = torch.rand((n, 1, 1, 1), generator=generator)
    grown = f.max_pool2d(paint, 3, 1, 1)
    shrunk = -f.max_pool2d(-paint, 3, 1, 1)
    paint = torch.where(which < 0.25, grown, torch.where(which < 0.5, shrunk, paint))
    return torch.cat([grey, paint], 1)


def train(torch, image, shape, labels, weights, seed, args):
    """Adam on class-weighted cross-entropy; returns the running average of
    the weights over the last steps (as markloop-train's --weight-average)."""
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    model = make_network(torch, args.dropout)
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-3, weight_decay=args.weight_decay)
    average = [p.detach().clone() for p in model.parameters()]
    n = labels.shape[0]
    step = 0
    for epoch in range(args.epochs):
        order = torch.randperm(n, generator=generator)
        total = 0.0
        for start in range(0, n, args.batch):
            idx = order[start:start + args.batch]
            batch = image[idx] if args.cutout <= 0 else cut_out(torch, image[idx], args.cutout, generator)
            if args.jitter:
                batch = jitter(torch, batch, generator)
            loss = (torch.nn.functional.cross_entropy(model(batch, shape[idx]), labels[idx],
                                                      reduction="none") * weights[idx]).mean()
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            step += 1
            decay = min(args.weight_average, (1.0 + step) / (10.0 + step))
            with torch.no_grad():
                for a, p in zip(average, model.parameters()):
                    a.mul_(decay).add_(p.detach(), alpha=1.0 - decay)
            total += float(loss) * len(idx)
        print(f"  epoch {epoch + 1}/{args.epochs}: loss {total / n:.4f}", flush=True)
    with torch.no_grad():
        for a, p in zip(average, model.parameters()):
            p.copy_(a)
    model.eval()
    return model


def probabilities(torch, model, image, shape):
    with torch.no_grad():
        parts = [torch.softmax(model(image[s:s + 4096], shape[s:s + 4096]), 1)
                 for s in range(0, image.shape[0], 4096)]
    return torch.cat(parts).numpy().astype(np.float32) if parts else np.zeros((0, K), np.float32)


def write_model(path, models, mean, inv_std, command, samples):
    """The final networks as a model file (app/perception/model/README.md:
    the shape features' standardisation, then each network's layers in
    PyTorch's order), and beside it PATH.txt saying how they were trained."""
    def values(v):
        return np.asarray(v, dtype=np.float32).ravel()

    layers = ["conv.0.weight", "conv.0.bias", "conv.3.weight", "conv.3.bias", "conv.6.weight", "conv.6.bias",
              "fc1.weight", "fc1.bias", "fc2.weight", "fc2.bias"]
    arrays = [values(mean), values(inv_std)]
    for model in models:
        state = model.state_dict()
        arrays += [values(state[name].numpy()) for name in layers]
    payload = np.concatenate(arrays).astype("<f4").tobytes()
    shape = [2, ROWS, COLS, SHAPE, C1, C2, C3, HIDDEN, K]
    model_file.write(path, "cnn", len(models), shape, payload)
    notes = os.path.splitext(path)[0] + ".txt"
    with open(notes, "w") as f:
        f.write(f"{os.path.basename(path)}: the marking classifier's convolutional networks, written by\n"
                "app/tools/train/train_cnn.py (format: app/perception/model/README.md). Regenerate with\n"
                "  app/tools/train/train-model.sh\n"
                "from the repository root, which runs\n"
                f"  {command}\n"
                f"{samples} training candidates; {len(models)} networks of marking_classifier.hpp (CnnModel).\n"
                f"Payload CRC-32 0x{zlib.crc32(payload):08x}.\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dump", help="directory markloop-train --dump wrote")
    ap.add_argument("--out", help="write the final networks as a model file (.bin) here, and how they were "
                    "trained beside it (.txt)")
    ap.add_argument("--folds", default="0,1,2,3,all",
                    help="comma-separated folds to hold out, 'all' for the final network (default %(default)s)")
    ap.add_argument("--epochs", type=int, default=15)
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--weight-decay", type=float, default=3e-3)
    ap.add_argument("--weight-average", type=float, default=0.9999)
    ap.add_argument("--real-weight", type=float, default=2.0)
    ap.add_argument("--reject-weight", type=float, default=2.5)
    ap.add_argument("--cutout", type=float, default=0.0,
                    help="share of training patches with a random rectangle erased (default %(default)s)")
    ap.add_argument("--jitter", action="store_true",
                    help="move, blur and add noise to the training patches, grow or shrink their paint")
    ap.add_argument("--dropout", type=float, default=0.0,
                    help="dropout on the hidden layer while training (default %(default)s)")
    ap.add_argument("--seeds", default="1,2",
                    help="comma-separated random seeds, one network of the ensemble each (default %(default)s)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads per training (default 1)")
    args = ap.parse_args()
    try:
        import torch
    except ImportError:
        sys.exit("train_cnn.py: python3-torch missing (bash .ci/setup train, or apt-get install python3-torch)")
    torch.set_num_threads(args.threads)
    index = os.path.join(args.dump, "sets.txt")
    if not os.path.isfile(index):
        sys.exit(f"train_cnn.py: {index}: no such file (run markloop-train --dump {args.dump})")
    sets = [line.split() for line in open(index)]
    train_names = [s[0] for s in sets if s[0].startswith("train")]
    test_names = [s[0] for s in sets if s[0].startswith("test")]
    seeds = [int(s) for s in args.seeds.split(",")]
    out_dirs = {seed: os.path.join(args.dump, "cnn", f"seed{seed}") for seed in seeds}
    for d in out_dirs.values():
        os.makedirs(d, exist_ok=True)

    parts = [load(os.path.join(args.dump, name)) for name in train_names]
    meta = np.concatenate([p[0] for p in parts])
    shape = np.concatenate([p[1] for p in parts])
    image = torch.from_numpy(np.concatenate([p[2] for p in parts]))
    real_count = parts[0][0].shape[0]  # train0: the real images (markloop-train's first set)
    labels, fold = meta[:, 0], meta[:, 3]
    real, augmented = meta[:, 4] == 1, meta[:, 5] == 1
    if not real[:real_count].any() and any(f != "all" for f in args.folds.split(",")):
        sys.exit(f"train_cnn.py: {train_names[0]} holds no real images (markloop-train without --real): "
                 "no folds to hold out, only --folds all")
    print(f"{int(real.sum())} of {meta.shape[0]} candidates real", flush=True)

    for name in args.folds.split(","):
        held_out = -1 if name == "all" else int(name)
        use = (labels >= 0) & ~(real & (fold == held_out))
        mean = shape[use].mean(0)
        inv_std = 1.0 / np.sqrt(shape[use].var(0) + 1e-4)
        y = labels[use]
        counts = np.bincount(y, minlength=K)
        class_weight = np.where(counts > 0, np.sqrt(y.size / (K * np.maximum(counts, 1))), 0.0)
        class_weight[REJECT] *= args.reject_weight
        weight = class_weight[y] * np.where(real[use], args.real_weight, 1.0)
        standard = lambda s: torch.from_numpy(((s - mean) * inv_std).astype(np.float32))
        print(f"fold {name}: {y.size} training candidates", flush=True)
        # The fold's training tensors, gathered once for all its seeds.
        fold_data = (image[torch.from_numpy(np.flatnonzero(use))], standard(shape[use]),
                     torch.from_numpy(y.astype(np.int64)), torch.from_numpy(weight.astype(np.float32)))
        models = []
        for seed in seeds:
            started = time.time()
            model = train(torch, *fold_data, seed, args)
            print(f"fold {name}, seed {seed}: {time.time() - started:.0f} s", flush=True)
            out_dir = out_dirs[seed]
            if held_out >= 0:
                idx = np.flatnonzero(real[:real_count] & (fold[:real_count] == held_out) & ~augmented[:real_count])
                real_probs = np.zeros((real_count, K), np.float32)
                real_probs[idx] = probabilities(torch, model, image[torch.from_numpy(idx)], standard(shape[idx]))
                real_probs.tofile(os.path.join(out_dir, f"train0.fold{held_out}.probs.f32"))
                continue
            for test in test_names:
                _, test_shape, test_image = load(os.path.join(args.dump, test))
                probabilities(torch, model, torch.from_numpy(test_image), standard(test_shape)).tofile(
                    os.path.join(out_dir, test + ".probs.f32"))
            models.append(model)
        del fold_data
        if models and args.out:
            command = "app/tools/train/train_cnn.py " + " ".join(
                a if not a.startswith("/") else os.path.relpath(a) for a in sys.argv[1:])
            write_model(args.out, models, mean, inv_std, command, y.size)
            print(f"wrote {args.out}", flush=True)
    folds = sorted(set(fold[:real_count][real[:real_count]].tolist()))
    for out_dir in out_dirs.values():
        fold_files = [os.path.join(out_dir, f"train0.fold{f}.probs.f32") for f in folds]
        if fold_files and all(os.path.isfile(f) for f in fold_files):
            sum(np.fromfile(f, dtype=np.float32) for f in fold_files).astype(np.float32).tofile(
                os.path.join(out_dir, "train0.probs.f32"))


if __name__ == "__main__":
    main()
