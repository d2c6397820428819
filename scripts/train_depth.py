"""Train the learned depth (issue 35, seed 003): a pix2pix-sized U-Net from frame 1's encoding (edges,
outline, the traced skeleton coloured by branch order and path length) to the skeleton's depth and
the crown's dual depth (front, interval to the back), on synthetic trees of every form
(``scripts/depth_data.py``), then exported to ONNX for ``cv2.dnn`` (``core/models/depth_unet.onnx``)
with a reference input and PyTorch's output beside it (``depth_unet_check.npz``: the tests hold
OpenCV's output in every runtime to it).

PyTorch is for training only (never a dependency of the extension); run it in a venv of its own:

    python3 -m venv /tmp/train && /tmp/train/bin/pip install -r requirements-train.txt
    /tmp/train/bin/python scripts/train_depth.py --train 3000 --epochs 16 [--data /tmp/depth_data]

Split by tree: training seeds ``0 … train−1``, validation ``500 000 + k``, test ``900 000 + k`` (never
trained on, never used to choose anything). Loss: the seed's L1 on the tree's pixels — per output
channel the mean absolute error over the pixels where its target is defined. The checkpoint kept
is the one with the lowest validation loss. ``--gan W`` adds a conditional PatchGAN's adversarial
loss (the seed's pix2pix; ``W = 0.01`` is its λ = 100): measured on 3,000 trees and 16 epochs it
did worse on every output (0.062 / 0.076 / 0.063 against the L1 alone's 0.060 / 0.071 / 0.054).
``--refine --dropout 0 --per-tree`` (a full-size convolution over the decoder's maps and the
input's one-pixel strokes, no dropout, the L1 per tree as the metric weights it) reached 0.059 /
0.071 / 0.053 at 2.4× the training time: the shipped model is the plain one.
Prints the test errors per form (unit depths: the seed's metric; targets ≤ 0.04 skeleton, ≤ 0.05
silhouette).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import depth_data  # noqa: E402

ld = depth_data.ld
VAL0, TEST0 = 500_000, 900_000


def unet(widths=(32, 64, 128, 128, 128), dropout: float = 0.3, refine: bool = False):
    """pix2pix's U-Net, narrower: 4×4 stride-2 convolutions down (batch norm but on the first, leaky
    ReLU 0.2), transposed convolutions up (batch norm, ReLU, ``dropout`` on the deepest two) with
    the encoder's maps concatenated, tanh out. ``refine``: the last transposed convolution gives
    ``widths[0]`` maps at full size, and a 3×3 convolution reads them beside the input encoding
    itself (the one-pixel strokes the stride-2 encoder only sees blurred) before the tanh."""
    import torch
    from torch import nn

    class UNet(nn.Module):
        def __init__(self):
            super().__init__()
            self.down = nn.ModuleList()
            c = ld.IN_CHANNELS
            for k, w in enumerate(widths):
                layers = [nn.Conv2d(c, w, 4, 2, 1, bias=k == 0)]
                if k:
                    layers.append(nn.BatchNorm2d(w))
                layers.append(nn.LeakyReLU(0.2))
                self.down.append(nn.Sequential(*layers))
                c = w
            self.up = nn.ModuleList()
            rev = list(widths[::-1])
            for k in range(len(widths) - 1):
                cin = rev[k] if k == 0 else rev[k] * 2
                layers = [nn.ConvTranspose2d(cin, rev[k + 1], 4, 2, 1, bias=False), nn.BatchNorm2d(rev[k + 1]),
                          nn.ReLU()]
                if k < 2 and dropout > 0:
                    layers.append(nn.Dropout(dropout))
                self.up.append(nn.Sequential(*layers))
            if refine:
                self.last = nn.Sequential(nn.ConvTranspose2d(widths[0] * 2, widths[0], 4, 2, 1, bias=False),
                                          nn.BatchNorm2d(widths[0]), nn.ReLU())
                self.out = nn.Sequential(nn.Conv2d(widths[0] + ld.IN_CHANNELS, ld.OUT_CHANNELS, 3, 1, 1), nn.Tanh())
            else:
                self.last = None
                self.out = nn.Sequential(nn.ConvTranspose2d(widths[0] * 2, ld.OUT_CHANNELS, 4, 2, 1), nn.Tanh())

        def forward(self, x):
            x0 = x
            skips = []
            for d in self.down:
                x = d(x)
                skips.append(x)
            skips.pop()
            for u in self.up:
                x = torch.cat([u(x), skips.pop()], 1)
            if self.last is not None:
                return self.out(torch.cat([self.last(x), x0], 1))
            return self.out(x)

    return UNet()


def patch_discriminator(widths=(32, 64, 128)):
    """pix2pix's conditional PatchGAN, narrower: the input encoding and a depth triple (tanh range)
    concatenated, 4×4 stride-2 convolutions (batch norm but on the first, leaky ReLU 0.2), then a
    4×4 stride-1 convolution to one logit per patch (a 128² input: 16 × 16 patches of 46 px)."""
    from torch import nn
    layers: list = []
    c = ld.IN_CHANNELS + ld.OUT_CHANNELS
    for k, w in enumerate(widths):
        layers.append(nn.Conv2d(c, w, 4, 2, 1, bias=k == 0))
        if k:
            layers.append(nn.BatchNorm2d(w))
        layers.append(nn.LeakyReLU(0.2))
        c = w
    layers.append(nn.Conv2d(c, 1, 3, 1, 1))
    return nn.Sequential(*layers)


def masked_l1(pred, y, w, per_tree: bool = False):
    """Per channel: mean |pred − y| over the pixels where ``w``; the channels' mean (unit depths,
    ``pred`` from tanh mapped to [0, 1]). ``per_tree``: each tree's mean first, then the trees'
    (the held-out metric's weighting: a sparse tree counts as much as a dense crown)."""
    p = (pred + 1.0) * 0.5
    err = (p - y).abs() * w
    if per_tree:
        n = w.sum((2, 3))                                            # (B, C)
        per_img = err.sum((2, 3)) / n.clamp(min=1.0)
        has = (n > 0).float()
        per = (per_img * has).sum(0) / has.sum(0).clamp(min=1.0)
        return per.mean(), per
    per = err.sum((0, 2, 3)) / w.sum((0, 2, 3)).clamp(min=1.0)
    return per.mean(), per


def tensors(data, idx):
    import torch
    x = torch.from_numpy(data["x"][idx].astype(np.float32) / 255.0)
    y = torch.from_numpy(depth_data.magnitudes(data["y"][idx].astype(np.float32)))
    w = torch.from_numpy(data["w"][idx].astype(np.float32))
    return x, y, w


def flip(x, y, w):
    """A mirrored tree is a tree: flip left-right."""
    return x.flip(3), y.flip(3), w.flip(3)


def evaluate(model, data, batch: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Per tree: mean absolute unit-depth error per channel ``(T, 3)`` (nan where undefined) and the
    pixels counted ``(T, 3)``."""
    import torch
    model.eval()
    errs, counts = [], []
    with torch.no_grad():
        for a in range(0, len(data["x"]), batch):
            x, y, w = tensors(data, slice(a, a + batch))
            p = (model(x) + 1.0) * 0.5
            e = ((p - y).abs() * w).sum((2, 3))
            n = w.sum((2, 3))
            errs.append((e / n.clamp(min=1.0)).numpy())
            counts.append(n.numpy())
    err, cnt = np.concatenate(errs), np.concatenate(counts)
    err[cnt == 0] = np.nan
    return err, cnt


def flat_errors(data) -> np.ndarray:
    """Per tree ``(T, 3)`` the error of a flat guess: every depth in the trunk's plane (0)."""
    guess = np.zeros(3, np.float32)[None, :, None, None]
    y, w = depth_data.magnitudes(data["y"].astype(np.float32)), data["w"]
    n = w.sum((2, 3))
    err = (np.abs(y - guess) * w).sum((2, 3)) / np.maximum(n, 1)
    err[n == 0] = np.nan
    return err


def report(err: np.ndarray, flat: np.ndarray, forms: np.ndarray, title: str) -> None:
    print(f"\n{title}: mean absolute error per tree, depth / height (seed 003's metric; targets skeleton ≤ "
          "0.04, silhouette ≤ 0.05); in brackets a flat guess's (every depth in the trunk's plane)")
    print("| form | trees | skeleton's distance from the plane | crown's reach | crown's interval |")
    print("|---|---|---|---|---|")
    for f in sorted(set(forms.tolist())) + ["all"]:
        sel = np.ones(len(forms), bool) if f == "all" else forms == f
        m, b = np.nanmean(err[sel], axis=0), np.nanmean(flat[sel], axis=0)
        print(f"| {f} | {sel.sum()} | " + " | ".join(f"{m[k]:.4f} ({b[k]:.4f})" for k in range(3)) + " |")


def export(model, path: str) -> None:
    """ONNX (opset 13, the TorchScript exporter) for cv2.dnn, and the check pair beside it."""
    import torch
    model.eval()
    x = torch.zeros(1, ld.IN_CHANNELS, ld.SIZE, ld.SIZE)
    tmp = path + ".tmp"
    torch.onnx.export(model, x, tmp, opset_version=13, dynamo=False, input_names=["x"], output_names=["y"])
    os.replace(tmp, path)
    sample = depth_data.sample(TEST0 + 999)
    xs = torch.from_numpy(sample["x"][None].astype(np.float32) / 255.0)
    with torch.no_grad():
        ys = model(xs).numpy()[0]               # tanh; learned_depth.DepthNet.run maps it to [0, 1]
    check = os.path.splitext(path)[0] + "_check.npz"
    np.savez_compressed(check, x=sample["x"], y=ys.astype(np.float32))
    import cv2
    net = cv2.dnn.readNetFromONNX(path)
    net.setInput(xs.numpy())
    diff = float(np.abs(net.forward()[0] - ys).max())
    print(f"exported {path} ({os.path.getsize(path) / 1e6:.1f} MB); cv2 {cv2.__version__} vs PyTorch: max |Δ| {diff:.2e}")


def main() -> None:
    import torch
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--train", type=int, default=3000, help="training trees")
    ap.add_argument("--val", type=int, default=200)
    ap.add_argument("--test", type=int, default=300)
    ap.add_argument("--epochs", type=int, default=16)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--lr", type=float, default=2e-4)
    ap.add_argument("--data", default=os.path.join("/tmp", "depth_data"), help="cache of the generated pairs")
    ap.add_argument("--out", default=ld.MODEL_PATH)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--gan", type=float, default=0.0,
                    help="weight of a conditional PatchGAN's adversarial loss beside the L1 (the seed's "
                         "pix2pix: 1 against λ = 100 for the L1, i.e. --gan 0.01); 0: L1 alone")
    ap.add_argument("--widths", default="32,64,128,128,128", help="the encoder's channels per level")
    ap.add_argument("--dropout", type=float, default=0.3, help="on the decoder's deepest two levels")
    ap.add_argument("--refine", action="store_true",
                    help="a full-size 3×3 convolution over the decoder's maps and the input encoding")
    ap.add_argument("--per-tree", action="store_true",
                    help="the L1 as each tree's mean, then the batch's (the metric's weighting)")
    args = ap.parse_args()
    torch.manual_seed(0)
    torch.set_num_threads(args.threads)
    os.makedirs(args.data, exist_ok=True)
    t0 = time.perf_counter()
    train = depth_data.cached(os.path.join(args.data, f"train_{args.train}.npz"), range(args.train))
    val = depth_data.cached(os.path.join(args.data, f"val_{args.val}.npz"), range(VAL0, VAL0 + args.val))
    test = depth_data.cached(os.path.join(args.data, f"test_{args.test}.npz"), range(TEST0, TEST0 + args.test))
    print(f"data: {len(train['x'])} / {len(val['x'])} / {len(test['x'])} trees in {time.perf_counter() - t0:.0f} s")
    model = unet(tuple(int(v) for v in args.widths.split(",")), args.dropout, args.refine)
    print(f"U-Net: {sum(p.numel() for p in model.parameters()) / 1e6:.2f} M parameters")
    opt = torch.optim.Adam(model.parameters(), lr=args.lr, betas=(0.5, 0.999))
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, args.epochs)
    disc = d_opt = None
    if args.gan > 0:
        disc = patch_discriminator()
        d_opt = torch.optim.Adam(disc.parameters(), lr=args.lr, betas=(0.5, 0.999))
        bce = torch.nn.BCEWithLogitsLoss()
    rng = np.random.default_rng(0)
    best, best_state = np.inf, None
    for epoch in range(args.epochs):
        model.train()
        order = rng.permutation(len(train["x"]))
        t = time.perf_counter()
        losses = []
        for a in range(0, len(order) - args.batch + 1, args.batch):
            x, y, w = tensors(train, np.sort(order[a:a + args.batch]))
            if rng.random() < 0.5:
                x, y, w = flip(x, y, w)
            pred = model(x)
            loss, _ = masked_l1(pred, y, w, args.per_tree)
            if disc is not None:             # pix2pix: D tells (x, truth) from (x, prediction)
                real = torch.cat([x, y * w * 2.0 - 1.0], 1)            # where defined, else -1
                fake = torch.cat([x, (pred + 1.0) * w - 1.0], 1)
                d_real, d_fake = disc(real), disc(fake.detach())
                d_loss = 0.5 * (bce(d_real, torch.ones_like(d_real)) + bce(d_fake, torch.zeros_like(d_fake)))
                d_opt.zero_grad()
                d_loss.backward()
                d_opt.step()
                g_adv = disc(fake)
                loss = loss + args.gan * bce(g_adv, torch.ones_like(g_adv))
            opt.zero_grad()
            loss.backward()
            opt.step()
            losses.append(loss.item())
        sched.step()
        v = np.nanmean(evaluate(model, val)[0], axis=0)
        print(f"epoch {epoch + 1}: train {np.mean(losses):.4f}, validation {v.round(4).tolist()} "
              f"({time.perf_counter() - t:.0f} s)", flush=True)
        if v.mean() < best:
            best, best_state = float(v.mean()), {k: t_.clone() for k, t_ in model.state_dict().items()}
    model.load_state_dict(best_state)
    # beside the data, never committed
    torch.save(best_state, os.path.join(args.data, os.path.splitext(os.path.basename(args.out))[0] + ".pt"))
    err = evaluate(model, test)[0]
    flat = flat_errors(test)
    report(err, flat, test["form"], f"held-out test trees ({len(test['x'])})")
    export(model, args.out)
    # the measured fit the lift reads (learned_depth.measured_fit), depth / height
    to_h = np.ones(3)
    doc = {"test_mae_over_height": (np.nanmean(err, 0) * to_h).round(5).tolist(),
           "flat_mae_over_height": (np.nanmean(flat, 0) * to_h).round(5).tolist(),
           "test_mae_unit_by_form": {f: np.nanmean(err[test["form"] == f], 0).round(5).tolist()
                                     for f in sorted(set(test["form"].tolist()))},
           "trees": {"train": args.train, "validation": args.val, "test": args.test}, "epochs": args.epochs,
           "gan": args.gan, "widths": args.widths, "dropout": args.dropout, "refine": args.refine,
           "per_tree": args.per_tree,
           "size": ld.SIZE, "inputs": ld.IN_CHANNELS, "outputs": ld.OUT_CHANNELS}
    fit = os.path.splitext(args.out)[0] + ".json"
    with open(fit + ".tmp", "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=1)
    os.replace(fit + ".tmp", fit)
    print(f"measured fit -> {fit}")


if __name__ == "__main__":
    main()
