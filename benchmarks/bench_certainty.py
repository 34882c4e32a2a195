"""Time EMMI (eq. 11) of M particles' grids: the fused numba kernel vs a naive NumPy expression.

    python scripts/bench_certainty.py [--particles 30 --side 256 --repeats 50]

Prints the median wall time of each over ``--repeats`` calls (after a warm-up call
that compiles or loads the cached kernels) and their ratio. Single thread.
"""

from __future__ import annotations

import argparse

import numpy as np

from _timing import median_seconds
from emmi_gym.certainty import emmi


def naive_emmi(p: np.ndarray, w: np.ndarray) -> float:
    """The straightforward NumPy version: EM by tensordot, then eqs. (7), (9), (10)."""
    em = np.tensordot(w, p, axes=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.nan_to_num(-(em * np.log2(em) + (1 - em) * np.log2(1 - em)))
    observed = h * np.log(2) < np.log(2) - 1e-3
    return float((1 - h)[observed].sum() / max(observed.sum(), 1))


def naive_emmi_logodds(l: np.ndarray, w: np.ndarray) -> float:
    return naive_emmi(1.0 / (1.0 + np.exp(-l)), w)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=30)
    parser.add_argument("--side", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    shape = (args.particles, args.side, args.side)
    # Realistic content: a third of the cells unknown, the rest near 0 or 1.
    prob = np.where(rng.random(shape) < 0.33, 0.5, rng.beta(0.3, 0.3, shape)).astype(np.float32)
    logodds = np.log(np.clip(prob, 1e-4, 1 - 1e-4) / np.clip(1 - prob, 1e-4, 1 - 1e-4)).astype(np.float32)
    w = rng.random(args.particles)
    w /= w.sum()
    # int8 codes of quantised log-odds with a probability table, as the RBPF stores its grids.
    codes = np.clip(np.round(logodds / 0.1), -127, 127).astype(np.int8)
    lut = 1.0 / (1.0 + np.exp(-0.1 * np.arange(-128, 128)))

    assert abs(emmi(prob, w) - naive_emmi(prob, w)) < 1e-6
    rows = [
        ("probabilities", 1000 * median_seconds(lambda: naive_emmi(prob, w), args.repeats),
         1000 * median_seconds(lambda: emmi(prob, w), args.repeats)),
        ("log-odds", 1000 * median_seconds(lambda: naive_emmi_logodds(logodds, w), args.repeats),
         1000 * median_seconds(lambda: emmi(logodds, w, logodds=True), args.repeats)),
        ("int8 codes+lut", 1000 * median_seconds(lambda: naive_emmi(lut[codes.astype(np.int64) + 128], w), args.repeats),
         1000 * median_seconds(lambda: emmi(codes, w, lut=lut), args.repeats)),
    ]
    print(f"EMMI of {args.particles} x {args.side} x {args.side} float32 grids, median of {args.repeats} calls")
    print(f"{'input':<15} {'naive NumPy ms':>15} {'emmi() ms':>10} {'speed-up':>9}")
    for name, naive, fused in rows:
        print(f"{name:<15} {naive:>15.2f} {fused:>10.2f} {naive / fused:>8.1f}x")


if __name__ == "__main__":
    main()
