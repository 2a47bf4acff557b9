#!/usr/bin/env python3
"""PyTorch CPU reference timings for the shapes of `egopd bench unet | vae_decode | vae_encode`.

Same network (svd_modules.py, checked against the golden cases by check_golden.py), same shapes, same inputs and,
by default, the very weights egopd's bench generates (its synthetic generator, re-implemented in svd_modules.py,
values rounded to F16 like egopd's default --dtype), computed in float32. Prints one JSON line.

    bench.py unet [--frames 16] [--size 256] [--pifr] [--batch 1]
    bench.py vae_decode [--frames 16] [--size 256] [--decode-chunk N]
    bench.py vae_encode [--frames 16] [--size 256]
    common: --threads N --repeat R --dtype f32 --weights egopd|seeded|DIR --weights-dtype f16|bf16|f32
"""

import argparse
import json
import math
import os
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ beside the sources

# ---- the shapes and conditioning of src/cli/bench_unet.cpp and src/cli/bench_vae.cpp --------------------------

SVD_XT_UNET = {  # unet3d.md section 1 (UNetConfig::svd_xt); "pifr" is set from --pifr
    "in_channels": 8, "out_channels": 4,
    "down_block_types": ["CrossAttnDownBlockSpatioTemporal"] * 3 + ["DownBlockSpatioTemporal"],
    "up_block_types": ["UpBlockSpatioTemporal"] + ["CrossAttnUpBlockSpatioTemporal"] * 3,
    "block_out_channels": [320, 640, 1280, 1280], "layers_per_block": 2, "transformer_layers_per_block": 1,
    "num_attention_heads": [5, 10, 20, 20], "cross_attention_dim": 1024,
    "addition_time_embed_dim": 256, "projection_class_embeddings_input_dim": 768,
}
SVD_XT_VAE = {  # vae.md section 1 (VaeConfig::svd_xt)
    "in_channels": 3, "out_channels": 3, "down_block_types": ["DownEncoderBlock2D"] * 4,
    "block_out_channels": [128, 256, 512, 512], "layers_per_block": 2, "latent_channels": 4,
    "scaling_factor": 0.18215,
}
UNET_TIMESTEP = 1.6377700567245483  # bench_unet.cpp's c_noise value
SYNTHETIC_SEED = 1234  # the seed bench_unet.cpp and bench_vae.cpp pass to the synthetic weight writer


def pattern(shape, mult, amp=1.0):
    """bench_*.cpp's deterministic inputs: amp * (((i * mult) % 2001) / 1000 - 1) in float32, i the flat index."""
    i = np.arange(math.prod(shape), dtype=np.int64)
    v = ((i * mult) % 2001).astype(np.float32) / np.float32(1000.0) - np.float32(1.0)
    return torch.from_numpy((np.float32(amp) * v).reshape(shape))


# ---- weights ------------------------------------------------------------------------------------------------------

def fill_synthetic(model, source, wdtype, seed=SYNTHETIC_SEED):
    """Overwrites every parameter: 'egopd' = egopd's bench weights exactly; 'seeded' = torch's generator with the
    same distributions (quicker to make; speed does not depend on the values)."""
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for name, p in model.state_dict().items():
            shape = list(p.shape)
            if source == "egopd":
                v = sm.egopd_synthetic(name, shape, seed)
            else:
                one_d = len(shape) <= 1
                if name.endswith("mix_factor"):
                    v = np.zeros(p.numel(), np.float32)
                elif one_d and name.endswith(".weight"):
                    v = np.ones(p.numel(), np.float32)
                else:
                    bound = 0.02 if one_d else 1.0 / math.sqrt(max(1, p.numel() // shape[0]))
                    v = (torch.rand(p.numel(), generator=gen) * (2 * bound) - bound).numpy()
            p.copy_(torch.from_numpy(sm.round_to(v, wdtype)).reshape(shape))


def make_model(kind, cfg, args):
    """(model, its config, a description of the weights)."""
    if args.weights in ("egopd", "seeded"):
        model = sm.build_model(kind, cfg).eval()
        fill_synthetic(model, args.weights, args.weights_dtype)
        return model, cfg, f"{args.weights} synthetic, {args.weights_dtype} values, seed {SYNTHETIC_SEED}"
    cfg = sm.read_config(args.weights)  # a diffusers component folder (unet/ or vae/): its own sizes
    model = sm.load_model_streaming(kind, args.weights)
    if kind == "unet" and bool((cfg.get("pifr") or {}).get("enabled", False)) != args.pifr:
        raise SystemExit("bench: --pifr must match the model folder's config (pifr.enabled)")
    return model, cfg, "folder " + os.path.basename(os.path.normpath(args.weights))


# ---- reporting ------------------------------------------------------------------------------------------------------

def proc_status_bytes(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return None


def reset_peak_rss():
    """Linux: writing 5 to clear_refs resets VmHWM, so the peak covers the timed calls, not the weight setup."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform
    return platform.processor() or platform.machine()


def cpu_capability():
    """ATen's vectorised-kernel level; torch.backends.cpu.get_cpu_capability() exists from torch 2.0 only."""
    cpu = getattr(torch.backends, "cpu", None)
    if cpu is not None and hasattr(cpu, "get_cpu_capability"):
        return cpu.get_cpu_capability()
    for line in torch.__config__.show().splitlines():
        if "CPU capability usage:" in line:
            return line.split(":", 1)[1].strip()
    return None


def blas_library():
    """The BLAS torch's matrix products went to (Debian's torch calls the system libblas.so.3, whichever
    implementation the alternatives system points it to), with OpenBLAS's kernel choice when it is OpenBLAS."""
    try:
        with open("/proc/self/maps") as f:
            libs = sorted({line.split()[-1] for line in f
                           if "blas" in line.split()[-1].lower() or "mkl" in line.split()[-1].lower()})
    except OSError:
        return None
    info = {"libraries": [os.path.basename(p) for p in libs if "/" in p]}
    for path in libs:
        if "openblas" in os.path.basename(path):
            try:
                import ctypes
                lib = ctypes.CDLL(path)
                lib.openblas_get_corename.restype = lib.openblas_get_config.restype = ctypes.c_char_p
                info["openblas_core"] = lib.openblas_get_corename().decode()
                info["openblas_config"] = lib.openblas_get_config().decode().strip()
                info["openblas_threads"] = lib.openblas_get_num_threads()
            except (OSError, AttributeError):
                pass
    return info


# ---- main -----------------------------------------------------------------------------------------------------------

def parse_args():
    ap = argparse.ArgumentParser(description="PyTorch CPU reference timing for the shapes of `egopd bench`.")
    ap.add_argument("target", choices=["unet", "vae_decode", "vae_encode"])
    ap.add_argument("--frames", type=int, default=16)
    ap.add_argument("--size", type=int, default=256, help="pixels (the U-Net's latent is size/8)")
    ap.add_argument("--threads", type=int, default=len(os.sched_getaffinity(0)))
    ap.add_argument("--repeat", type=int, default=3, help="timed calls after the warm-up; the lower median is reported")
    ap.add_argument("--dtype", choices=["f32"], default="f32", help="compute precision (float32 only)")
    ap.add_argument("--weights", default="egopd",
                    help="egopd (egopd bench's synthetic weights, bit for bit), seeded (torch generator, same "
                         "distributions) or a diffusers component folder (unet/ or vae/ of a model directory)")
    ap.add_argument("--weights-dtype", choices=["f16", "bf16", "f32"], default="f16",
                    help="storage precision the synthetic values are rounded to (egopd bench --dtype; default f16)")
    ap.add_argument("--pifr", action="store_true", help="unet: with the PIFR layers and 77 text tokens (egopd --pifr)")
    ap.add_argument("--batch", type=int, default=1,
                    help="unet: videos per call (egopd bench unet runs 1; 2 = a classifier-free-guidance pass)")
    ap.add_argument("--decode-chunk", type=int, default=0, help="vae_decode: frames per chunk (0 = all, egopd's default)")
    args = ap.parse_args()
    if args.frames < 1 or args.size < 8 or args.size % 8 or args.repeat < 1 or args.threads < 1 or args.batch < 1:
        ap.error("need --frames >= 1, --size a positive multiple of 8, --repeat >= 1, --threads >= 1, --batch >= 1")
    if args.target == "unet" and args.size % 64:
        ap.error("unet: --size must be a multiple of 64 (three 2x downsamplings of the size/8 latent)")
    return args


def main():
    args = parse_args()
    # Thread counts must be fixed before torch and its BLAS start their thread pools: torch.set_num_threads does
    # not reach OpenBLAS, which Debian's torch calls for every matrix product.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(args.threads)
    global torch, np, sm
    import numpy as np
    import torch
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import svd_modules as sm
    torch.set_num_threads(args.threads)

    t_setup = time.perf_counter()
    report = {"target": args.target}
    lat = args.size // 8
    if args.target == "unet":
        cfg = dict(SVD_XT_UNET, pifr={"text_dim": 1024, "enabled": True} if args.pifr else None)
        model, cfg, source = make_model("unet", cfg, args)
        b = args.batch
        ctx = cfg["cross_attention_dim"]
        ctx = ctx[0] if isinstance(ctx, list) else ctx
        # bench_unet.cpp's inputs, repeated over the batch (it runs one video)
        sample = pattern([1, args.frames, cfg["in_channels"], lat, lat], 7919).repeat(b, 1, 1, 1, 1)
        ehs = pattern([1, 1, ctx], 104729).repeat(b, 1, 1)
        ids = torch.tensor([[4.0, 127.0, 0.02]]).repeat(b, 1)
        text = pattern([1, 77, cfg["pifr"]["text_dim"]], 31).repeat(b, 1, 1) if args.pifr else None
        timestep = torch.tensor([UNET_TIMESTEP], dtype=torch.float32)
        call = lambda: model(sample, timestep, ehs, ids, text)  # noqa: E731
        report.update(frames=args.frames, size=args.size, latent=f"{lat}x{lat}", batch=b, pifr=args.pifr)
    else:
        model, cfg, source = make_model("vae", SVD_XT_VAE, args)
        if args.target == "vae_decode":
            chunk = args.decode_chunk or args.frames
            latents = pattern([args.frames, cfg["latent_channels"], lat, lat], 7919)
            call = lambda: model.decode_latents(latents, args.frames, chunk)  # noqa: E731
            report.update(frames=args.frames, size=args.size, decode_chunk=chunk)
        else:
            images = pattern([args.frames, cfg["in_channels"], args.size, args.size], 7919)
            call = lambda: model.encode(images)[0]  # noqa: E731  (mode() = the mean, as egopd's encode_mean)
            report.update(frames=args.frames, size=args.size)
    weights_bytes = sum(p.numel() * p.element_size() for p in model.state_dict().values())
    setup_seconds = time.perf_counter() - t_setup
    rss_setup = proc_status_bytes("VmRSS")
    peak_reset = reset_peak_rss()

    secs, cpu = [], []
    with torch.inference_mode():
        t0 = time.perf_counter()
        out = call()  # warm-up: first-touch of buffers, oneDNN primitive creation
        warmup = time.perf_counter() - t0
        print(f"bench {args.target}: warm-up {warmup:.2f} s", file=sys.stderr)
        for r in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            out = call()
            secs.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            print(f"bench {args.target}: call {r + 1}/{args.repeat} {secs[-1]:.2f} s", file=sys.stderr)
    o = out.double()
    report.update(
        seconds=sorted(secs)[(len(secs) - 1) // 2],  # lower median, as egopd bench reports
        cpu_seconds=sorted(cpu)[(len(cpu) - 1) // 2],
        seconds_all=secs, warmup_seconds=warmup, repeat=args.repeat, threads=torch.get_num_threads(),
        dtype=args.dtype, weights=source, weights_bytes=weights_bytes, setup_seconds=setup_seconds,
        torch=torch.__version__, numpy=np.__version__,
        mkldnn={"available": torch.backends.mkldnn.is_available(), "enabled": torch.backends.mkldnn.enabled},
        cpu_capability=cpu_capability(), blas=blas_library(), cpu=cpu_model(), logical_cpus=os.cpu_count(),
        env={k: os.environ[k] for k in ("ATEN_CPU_CAPABILITY", "OPENBLAS_CORETYPE", "ONEDNN_MAX_CPU_ISA",
                                        "DNNL_MAX_CPU_ISA") if k in os.environ},
        rss_after_setup_bytes=rss_setup,
        peak_rss_bytes=proc_status_bytes("VmHWM"),
        peak_rss_scope="timed calls (weights included)" if peak_reset else "whole process",
        output_shape=list(out.shape), output_finite=bool(torch.isfinite(o).all()),
        output_rms=math.sqrt(float((o * o).mean())),
    )
    print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
