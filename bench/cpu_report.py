#!/usr/bin/python3
"""The per-CPU figures of egopd's kernel paths, measured side by side in one run on this machine.

For every kernel path the CPU has (avx512, avx2, neon; not portable, which is for correctness): the real-size U-Net
evaluation in fp32, VAE decode 16 x 256x256 and a whole 4-step run; on the default path the U-Net in bf16 and int8
too, and with --conv direct (whose share of the peak is the kernels' own: Winograd's runs count the FLOPs they save);
PyTorch CPU's U-Net (bench/pytorch/bench.py) for the ratio. The measurements alternate, ROUNDS times, so that a
shared host's drift hits them alike; the table gives the minimum and median seconds, each row's ratio to the
default path's fp32 figure (or to PyTorch), median share of the peak and largest peak RSS, and the CPU, kernel
flags and measured peak it ran on. Then the GEMM and 3x3 convolution kernels against OpenBLAS and oneDNN
(kernels_bench through bench/alternate.sh). What cannot run (no PyTorch, kernels_bench built without
OpenBLAS/oneDNN) is reported as skipped.

On an AVX-512 CPU the references are also asked for their AVX-512 code, since their defaults may not use it
(Debian's torch 1.13 runs ATen's AVX2 kernels, and OpenBLAS 0.3.21 does not know Zen 5 and falls back to its
Haswell kernels): PyTorch gets a second row with ATEN_CPU_CAPABILITY=avx512 and OPENBLAS_CORETYPE=Cooperlake
(SkylakeX without AVX512-BF16), and the GEMM comparison runs OpenBLAS with that core type. Otherwise OpenBLAS
chooses its own kernels: a core type or L2 size pinned in the caller's environment (OPENBLAS_CORETYPE,
OPENBLAS_L2_SIZE) is removed from every reference run, and the report names the core type used.

usage: bench/cpu_report.py [--rounds N] [--quick] [--direct-pairs] [--egopd PATH] [--kernels-bench PATH]
  --rounds N      alternations (default 3; a real-size round takes 10-15 minutes on 2 cores)
  --quick         2 frames of 64x64 and the tiny pipeline: a smoke test of the script (~3 minutes)
  --direct-pairs  also VAE encode, and VAE encode, VAE decode and the 4-step run with --conv direct on the default
                  path: the direct rows' ratios are Winograd's gain (about 6 more minutes per round on a Zen 4)
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_json(argv, env=None):
    """Runs a bench command and returns its last JSON line (the report)."""
    p = subprocess.run(argv, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)}: exit {p.returncode}: {p.stderr.strip().splitlines()[-1:]}")
    lines = [l for l in p.stdout.splitlines() if l.startswith("{")]
    if not lines:
        raise RuntimeError(f"{' '.join(argv)}: no JSON report")
    return json.loads(lines[-1])


def kernel_paths(egopd):
    """The paths this CPU runs, widest first, and the default one (from egopd --version)."""
    env = {k: v for k, v in os.environ.items() if k != "EGOPD_KERNELS"}
    default = re.search(r"kernels: (\w+)", subprocess.run([egopd, "--version"], env=env, capture_output=True,
                                                          text=True, check=True).stdout).group(1)
    paths = []
    for path in ("avx512", "avx2", "neon"):
        r = subprocess.run([egopd, "--version"], env={**env, "EGOPD_KERNELS": path}, capture_output=True, text=True)
        if r.returncode == 0:
            paths.append(path)
    return paths, default


# A reference run's settings over the caller's environment (None: removed, so that the library chooses itself).
STOCK_REFERENCE_ENV = {"ATEN_CPU_CAPABILITY": None, "OPENBLAS_CORETYPE": None, "OPENBLAS_L2_SIZE": None}


def reference_avx512_env(egopd, default):
    """The settings that put PyTorch and OpenBLAS on their AVX-512 kernels ({} unless the path is avx512)."""
    if default != "avx512":
        return {}
    version = subprocess.run([egopd, "--version"], capture_output=True, text=True, check=True).stdout
    core = "Cooperlake" if "bf16: vdpbf16ps" in version else "SkylakeX"
    return {**STOCK_REFERENCE_ENV, "ATEN_CPU_CAPABILITY": "avx512", "OPENBLAS_CORETYPE": core}


def with_settings(env, settings):
    """env with settings applied (a value of None removes the variable)."""
    env = dict(env)
    for k, v in settings.items():
        if v is None:
            env.pop(k, None)
        else:
            env[k] = v
    return env


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--direct-pairs", action="store_true")
    ap.add_argument("--egopd", default=os.path.join(ROOT, "build/bin/egopd"))
    ap.add_argument("--kernels-bench", default=os.path.join(ROOT, "build/bin/kernels_bench"))
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    a = ap.parse_args()
    if a.rounds < 1:
        sys.exit("cpu_report: --rounds must be at least 1")
    if not os.access(a.egopd, os.X_OK):
        sys.exit(f"cpu_report: {a.egopd}: not built (scripts/build.sh)")

    frames, size = ("2", "64") if a.quick else ("16", "256")
    threads = str(a.threads)
    paths, default = kernel_paths(a.egopd)
    def bench(target, *options):
        return [a.egopd, "bench", target, *options, "--threads", threads, "--json"]

    clip = ("--frames", frames, "--size", size)
    unet = bench("unet", *clip, "--pifr", "--evals", "1")
    vae = bench("vae_decode", *clip)
    vae_encode = bench("vae_encode", *clip)
    pipe = bench("pipeline", "--steps", "4", *(("--config", "tiny") + clip if a.quick else ()))

    # (label, argv, EGOPD_KERNELS or None, baseline label, further environment)
    jobs = []
    for path in paths:
        jobs.append((f"U-Net fp32, {path}", unet, path, f"U-Net fp32, {default}", {}))
    # The direct convolutions do all the arithmetic the FLOP count assumes: their share of the peak is the kernels'.
    jobs.append((f"U-Net fp32 --conv direct, {default}", unet + ["--conv", "direct"], default,
                 f"U-Net fp32, {default}", {}))
    for precision in ("bf16", "int8"):
        jobs.append((f"U-Net {precision}, {default}", unet + ["--precision", precision], default,
                     f"U-Net fp32, {default}", {}))
    for path in paths:
        jobs.append((f"VAE decode, {path}", vae, path, f"VAE decode, {default}", {}))
    for path in paths:
        jobs.append((f"4-step run, {path}", pipe, path, f"4-step run, {default}", {}))
    if a.direct_pairs:  # what Winograd (--conv auto) gains over the direct convolutions, stage by stage
        jobs.append((f"VAE encode, {default}", vae_encode, default, f"VAE encode, {default}", {}))
        for what, argv in (("VAE encode", vae_encode), ("VAE decode", vae), ("4-step run", pipe)):
            jobs.append((f"{what} --conv direct, {default}", argv + ["--conv", "direct"], default,
                         f"{what}, {default}", {}))
    # Asked of the interpreter that runs the PyTorch job, not of this one (python3 may be another installation).
    torch_python = "/usr/bin/python3"
    torch_jobs = []
    reference_env = reference_avx512_env(a.egopd, default)
    if subprocess.run([torch_python, "-c", "import torch"], capture_output=True).returncode == 0:
        torch_unet = [torch_python, os.path.join(ROOT, "bench/pytorch/bench.py"), "unet", "--frames", frames,
                      "--size", size, "--pifr", "--threads", threads, "--repeat", "1"]
        # The stock row runs without the caller's ATen / OpenBLAS settings, the other with the AVX-512 ones.
        torch_jobs.append(("PyTorch U-Net fp32", torch_unet, None, None, STOCK_REFERENCE_ENV))
        if reference_env:
            torch_jobs.append((f"PyTorch U-Net fp32 (ATen avx512, OpenBLAS {reference_env['OPENBLAS_CORETYPE']})",
                               torch_unet, None, None, reference_env))
    else:
        print(f"cpu_report: {torch_python} cannot import torch (Debian: python3-torch): no PyTorch row",
              file=sys.stderr)

    times = {}
    rss = {}  # label -> peak resident set of each run, bytes
    shares = {}  # label -> percent_of_peak of each run (direct-fp32-equivalent FLOPs over the peak measured beside it)
    facts = {}
    for r in range(a.rounds):
        for label, argv, path, _, extra_env in jobs + torch_jobs:
            env = with_settings(os.environ, {**extra_env, "EGOPD_KERNELS": path})
            rep = run_json(argv, env)
            times.setdefault(label, []).append(rep["seconds"])
            if "peak_rss_bytes" in rep:
                rss.setdefault(label, []).append(rep["peak_rss_bytes"])
            if "percent_of_peak" in rep:
                shares.setdefault(label, []).append(rep["percent_of_peak"])
            if path:  # egopd's report: the CPU, and per path its flags and measured FP32 peak
                facts["cpu"] = rep.get("cpu", "?")
                facts.setdefault("flags", {})[path] = rep.get("kernel_features", "?")
                facts.setdefault("peak", {}).setdefault(path, []).append(rep["peak_gflops"])
            print(f"round {r + 1}/{a.rounds}: {label}: {rep['seconds']:.2f} s", file=sys.stderr, flush=True)

    print(f"CPU: {facts['cpu']}; {a.threads} threads; kernel paths (flags; measured FP32 peak): "
          + ", ".join(f"{p} ({f}; {min(facts['peak'][p]):.0f}-{max(facts['peak'][p]):.0f} GFLOP/s)"
                      for p, f in facts["flags"].items()) + f"; default {default}")
    print(f"{a.rounds} alternating rounds, {frames} frames of {size}x{size}\n")
    print("| work | min s | median s | ratio of medians | % of peak (median; direct-fp32-equivalent FLOPs) | peak RSS |")
    print("|---|---|---|---|---|---|")
    for label, _, _, base, _ in jobs + torch_jobs:
        t = times[label]
        if label.startswith("PyTorch"):
            ratio = "1.00 (egopd fp32 " + default + ": " + \
                f"{statistics.median(times[f'U-Net fp32, {default}']) / statistics.median(t):.2f}x its time)"
        else:
            # Also the median of the rounds' own ratios: a host that switches between speeds from run to run moves
            # the two medians apart, while a round's pair ran minutes apart.
            per_round = statistics.median(b / x for b, x in zip(times[base], t))
            ratio = (f"{statistics.median(times[base]) / statistics.median(t):.2f}x speed of {base} "
                     f"(per round: median {per_round:.2f}x)")
        share = f"{statistics.median(shares[label]):.1f}%" if label in shares else "-"
        mem = f"{max(rss[label]) / 1e9:.2f} GB" if label in rss else "-"
        print(f"| {label} | {min(t):.2f} | {statistics.median(t):.2f} | {ratio} | {share} | {mem} |")

    kb = a.kernels_bench
    if not os.access(kb, os.X_OK):
        print(f"\ncpu_report: {kb}: not built (EGOPD_BUILD_BENCH=ON and libbenchmark-dev): no kernel rows")
        return
    listed = subprocess.run([kb, "--benchmark_list_tests"], capture_output=True, text=True).stdout
    # Pairs of the same shape: egopd's F32 GEMM against OpenBLAS's SGEMM; egopd's direct 3x3 convolution (F32
    # weights, EGOPD_CONV=direct: kernel against kernel) against oneDNN's direct convolution on its blocked layouts.
    for what, pattern, needed, pair in (
            ("GEMM", "BM_(egopd_gemm/.*dt:0|openblas_sgemm)/", "openblas",
             lambda n: n.replace("BM_egopd_gemm/", "BM_openblas_sgemm/")),
            ("3x3 convolution (egopd direct)", "BM_(egopd_conv3x3/.*v:0|onednn_conv3x3/.*v:1)/", "onednn",
             lambda n: n.replace("BM_egopd_conv3x3/", "BM_onednn_conv3x3/").replace("/v:0", "/v:1"))):
        if f"BM_{needed}" not in listed:
            print(f"\n{what}: skipped ({kb} was built without {needed})")
            continue
        env = with_settings(os.environ, {**(reference_env or STOCK_REFERENCE_ENV), "EGOPD_CONV": "direct"})
        out = subprocess.run([os.path.join(ROOT, "bench/alternate.sh"), str(a.rounds), pattern, kb], env=env,
                             capture_output=True, text=True, check=True).stdout
        median = {}
        for line in out.splitlines():  # NAME BINARY min X median Y UNIT (n=R)
            f = line.split()
            median[f[0]] = (float(f[3]), float(f[5]), f[6])
        core = f", OPENBLAS_CORETYPE={env.get('OPENBLAS_CORETYPE', 'unset: its own choice')}" \
            if needed == "openblas" else ""
        print(f"\n{what} against {needed} ({os.path.basename(kb)}{core}, {a.rounds} alternating rounds; ratio of "
              f"medians, > 1: egopd faster)\n")
        print(f"| shape | egopd min / median | {needed} min / median | ratio |")
        print("|---|---|---|---|")
        for name, (lo, med, unit) in sorted(median.items()):
            other = median.get(pair(name))
            if not name.startswith("BM_egopd") or other is None:
                continue
            shape = re.sub(r"/(dt|v):\d+/real_time$", "", name.split("/", 1)[1])
            print(f"| {shape} | {lo:.2f} / {med:.2f} {unit} | {other[0]:.2f} / {other[1]:.2f} {other[2]} | "
                  f"{other[1] / med:.2f}x |")

if __name__ == "__main__":
    try:
        main()
    except (RuntimeError, subprocess.CalledProcessError) as e:
        sys.exit(f"cpu_report: {e}")
