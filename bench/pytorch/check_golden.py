#!/usr/bin/env python3
"""Runs the PyTorch modules of svd_modules.py on the golden cases of tests/data/golden (unet, unet_pifr_*,
vae_decode, vae_encode) and compares with expected.safetensors under each case's tolerances.

The check runs in float64, as the expected values were made; the float32 errors are printed beside it for
orientation (they should be close to the case's reference_fp32_error). A pass shows that bench.py times the same
network as egopd. Exit status 0 = every case passes. Takes a few seconds.
"""

import argparse
import json
import os
import sys

import torch

sys.dont_write_bytecode = True  # no __pycache__ beside the sources
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import svd_modules as sm  # noqa: E402

CASES = ["unet", "unet_pifr_random", "unet_pifr_zero_init", "vae_decode", "vae_encode"]


def run_case(case_dir, case, dtype):
    """The case's outputs from our modules, computed in `dtype`."""
    inputs = sm.read_safetensors(os.path.join(case_dir, case["inputs"]), dtype)
    model_dir = os.path.join(case_dir, case["model_dir"])
    component = case["component"]
    with torch.inference_mode():
        if component in ("unet", "unet_pifr"):
            model = sm.load_model("unet", model_dir, dtype)
            out = model(inputs["sample"], inputs["timestep"], inputs["encoder_hidden_states"],
                        inputs["added_time_ids"], inputs.get("text_tokens"))
            return {"sample": out}
        model = sm.load_model("vae", model_dir, dtype)
        if component == "vae_decode":
            return {"sample": model.decode(inputs["z"], case["args"]["num_frames"])}
        if component == "vae_encode":
            mean, logvar = model.encode(inputs["image"])
            return {"latent_mean": mean, "latent_logvar": logvar}
    raise ValueError(f"unsupported component {component}")


def check_synthetic_model(root, model_seed):
    """bench.py's 'egopd' weights against a model folder written by `egopd-convert synth --seed S` (or bench
    pipeline, S = 0): every U-Net and VAE tensor must be equal bit for bit. Returns the number of differing tensors."""
    golden_ratio = 0x9E3779B97F4A7C15
    bad = 0
    # write_synthetic_model gives component k (unet 0, vae 1) the seed (S + k) * golden_ratio + 1.
    for k, kind in enumerate(["unet", "vae"]):
        seed = ((model_seed + k) * golden_ratio + 1) & sm.M64
        folder = os.path.join(root, kind)
        differ = total = 0
        for path in sm.component_weight_files(folder):
            with open(path, "rb") as f:
                header = json.loads(f.read(int.from_bytes(f.read(8), "little")))
            for name, t in sm.iter_safetensors(path):
                stored = header[name]["dtype"].lower()
                mine = sm.round_to(sm.egopd_synthetic(name, list(t.shape), seed), stored)
                same = (mine.view("uint32") == t.numpy().reshape(-1).view("uint32")).all()
                differ += not same
                total += 1
        print(f"synthetic {kind:5} {total:5} tensors, {differ} differ  {'pass' if differ == 0 else 'FAIL'}")
        bad += differ
    return bad


def errors(out, expected):
    d = (out.double() - expected.double())
    return d.abs().max().item(), (d.norm() / expected.double().norm()).item()


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--golden", default=os.path.join(here, "..", "..", "tests", "data", "golden"),
                    help="golden cases folder (default: the repository's tests/data/golden)")
    ap.add_argument("--json", action="store_true", help="one JSON line per output instead of the table")
    ap.add_argument("--synthetic-model", metavar="DIR",
                    help="also check bench.py's egopd weights against this egopd synthetic model folder")
    ap.add_argument("--model-seed", type=int, default=0, help="the --seed that folder was written with (default 0)")
    ap.add_argument("cases", nargs="*", default=CASES, help=f"case names (default: {' '.join(CASES)})")
    args = ap.parse_args()
    torch.set_num_threads(1)  # tiny cases: threads would only add noise to a shared machine

    failed = 0
    if not args.json:
        print(f"{'case':22} {'output':14} {'f64 max_abs':>12} {'tol':>9} {'f64 rel_l2':>11} {'tol':>9} "
              f"{'f32 max_abs':>12} {'f32 rel_l2':>11}  result")
    for name in args.cases:
        case_dir = os.path.join(args.golden, name)
        with open(os.path.join(case_dir, "case.json")) as f:
            case = json.load(f)
        expected = sm.read_safetensors(os.path.join(case_dir, case["expected"]), torch.float64)
        out64 = run_case(case_dir, case, torch.float64)
        out32 = run_case(case_dir, case, torch.float32)
        for key, tol in case["tolerance"].items():
            if out64[key].shape != expected[key].shape:
                raise SystemExit(f"{name}/{key}: shape {list(out64[key].shape)}, expected {list(expected[key].shape)}")
            a64, r64 = errors(out64[key], expected[key])
            a32, r32 = errors(out32[key], expected[key])
            ok = torch.isfinite(out64[key]).all().item() and a64 <= tol["max_abs"] and r64 <= tol["rel_l2"]
            failed += not ok
            if args.json:
                print(json.dumps({"case": name, "output": key, "f64_max_abs": a64, "f64_rel_l2": r64,
                                  "tol_max_abs": tol["max_abs"], "tol_rel_l2": tol["rel_l2"],
                                  "f32_max_abs": a32, "f32_rel_l2": r32, "pass": bool(ok)}))
            else:
                print(f"{name:22} {key:14} {a64:12.3e} {tol['max_abs']:9.2e} {r64:11.3e} {tol['rel_l2']:9.2e} "
                      f"{a32:12.3e} {r32:11.3e}  {'pass' if ok else 'FAIL'}")
    if failed:
        print(f"{failed} output(s) outside tolerance", file=sys.stderr)
    if args.synthetic_model:
        failed += check_synthetic_model(args.synthetic_model, args.model_seed)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
