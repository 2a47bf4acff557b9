#!/usr/bin/env python3
"""Counterfactual weight sweep: the same clip and seed under several object weights; total force per frame per
weight written as a plot (with matplotlib, when installed) and as a CSV.

    python3 examples/python/weight_sweep.py [--model DIR] [--video CLIP] [--weights 1,355,1000,omit]
                                            [--frames 16] [--size 256] [--out sweep]

Without --model / --video: the built-in tiny synthetic model and sample clip (forces not meaningful).
"""
import argparse
import os
import sys

import egopd


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model")
    ap.add_argument("--video")
    ap.add_argument("--meta", help="META.json with the other prompt fields")
    ap.add_argument("--weights", default="1,355,1000,omit")
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="sweep")
    a = ap.parse_args()

    model = egopd.Model(a.model, size=a.size)

    def progress(p):
        if p.stage == "denoise":
            print(f"\r  variant {p.variant}/{p.variants} step {p.step}/{p.steps}", end="", file=sys.stderr, flush=True)

    meta = a.meta or {"obj_name": "a CocaCola", "material": "aluminum"}
    results = model.counterfactual("weight=" + a.weights, video=a.video, meta=meta, num_frames=a.frames,
                                   seed=a.seed, progress=progress)
    print(file=sys.stderr)
    os.makedirs(a.out, exist_ok=True)
    csv = os.path.join(a.out, "force_per_frame.csv")
    with open(csv, "w") as f:
        f.write("weight," + ",".join(f"frame{i}" for i in range(len(results[0].total_force))) + "\n")
        for r in results:
            f.write(r.variant + "," + ",".join(f"{v:.6g}" for v in r.total_force) + "\n")
    for r in results:
        print(f"weight {r.variant:>8}: mean {r.mean_force:9.2f} N, peak {r.peak_force:9.2f} N")
    print("wrote", csv)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no plot (apt-get install python3-matplotlib)")
        return 0
    fig, ax = plt.subplots(figsize=(7, 4))
    for r in results:
        ax.plot(range(len(r.total_force)), r.total_force, marker="o", label=f"weight {r.variant}")
    ax.set_xlabel("frame")
    ax.set_ylabel("total force (N)")
    ax.set_title("Counterfactual weight sweep" + (" (synthetic model)" if results[0].summary["model_synthetic"] else ""))
    ax.legend()
    fig.tight_layout()
    png = os.path.join(a.out, "force_per_frame.png")
    fig.savefig(png, dpi=100)
    print("wrote", png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
