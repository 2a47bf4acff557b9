"""egopd: grasp pressure (162 glove taxels in newtons, and heatmaps) from an RGB clip with an EgoPressureDiff model
on the CPU, through the C library libegopd.so (include/egopd.h).

    import egopd
    model = egopd.Model()                      # no path: the built-in tiny synthetic model
    result = model.predict(seed=0)             # no video/frames: the built-in sample clip
    result.taxels                              # numpy float64 [F, 162], newtons (taxels.csv)
    result.heatmaps                            # numpy float32 [F, S, S] in [0, 1]
    result.summary                             # dict (summary.json)

Options have the names and defaults of `egopd predict` (num_frames is --frames). Errors raise egopd.Error with the
command's one-line message; a progress callback returning False (or raising) cancels the run, and Ctrl-C cancels
it at the next sampler step; the model stays usable either way.

The library is found through EGOPD_LIBRARY (a path to libegopd.so.0), else in the prefix this module was installed
into (PREFIX/lib*/), else by the dynamic loader (libegopd.so.0).
"""
import ctypes
import json
import os
import pathlib
import signal
import threading

import numpy as np

__all__ = ["Model", "Result", "Progress", "Error", "ArgumentError", "Cancelled", "version"]

OK, ERROR, ERROR_ARGUMENT, CANCELLED, INTERRUPTED, ERROR_MEMORY = range(6)


class Error(Exception):
    """A failed call: the message is egopd's one-line error."""


class ArgumentError(Error, ValueError):
    """A bad argument: a mis-sized array, an option out of range, a missing file."""


class Cancelled(Error):
    """The progress callback asked to stop."""


_LOG_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p)


class _Progress(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t), ("stage", ctypes.c_char_p), ("step", ctypes.c_int),
                ("steps", ctypes.c_int), ("step_seconds", ctypes.c_double), ("elapsed_seconds", ctypes.c_double),
                ("variant", ctypes.c_int), ("variants", ctypes.c_int)]


_PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(_Progress))


class _LoadOptions(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t), ("threads", ctypes.c_int), ("low_mem", ctypes.c_int),
                ("precision", ctypes.c_char_p), ("size", ctypes.c_int64), ("template_path", ctypes.c_char_p),
                ("log", _LOG_FN), ("log_user", ctypes.c_void_p), ("conv", ctypes.c_char_p),
                ("block_cache_mb", ctypes.c_int64)]


class _PredictOptions(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_size_t),
                ("video", ctypes.c_char_p),
                ("frames", ctypes.c_void_p), ("frames_bytes", ctypes.c_size_t), ("frames_count", ctypes.c_int64),
                ("frames_height", ctypes.c_int64), ("frames_width", ctypes.c_int64),
                ("masks_dir", ctypes.c_char_p),
                ("masks", ctypes.c_void_p), ("masks_bytes", ctypes.c_size_t), ("masks_count", ctypes.c_int64),
                ("masks_height", ctypes.c_int64), ("masks_width", ctypes.c_int64),
                ("prompt", ctypes.c_char_p), ("meta_path", ctypes.c_char_p), ("meta_json", ctypes.c_char_p),
                ("sampler", ctypes.c_char_p), ("steps", ctypes.c_int), ("seed", ctypes.c_uint64),
                ("num_frames", ctypes.c_int64), ("size", ctypes.c_int64), ("has_guidance", ctypes.c_int),
                ("guidance_min", ctypes.c_float), ("guidance_max", ctypes.c_float),
                ("decode_chunk", ctypes.c_int64), ("out_dir", ctypes.c_char_p),
                ("progress", _PROGRESS_FN), ("progress_user", ctypes.c_void_p)]


def _library_candidates():
    env = os.environ.get("EGOPD_LIBRARY")
    if env:
        return [env]
    here = pathlib.Path(__file__).resolve().parent
    out = []
    # PREFIX/lib/python3.X/dist-packages/egopd/ or PREFIX/lib/python3/dist-packages/egopd/
    if len(here.parents) > 3:
        prefix = here.parents[3]
        for lib in sorted(prefix.glob("lib*")):
            out += [str(p) for p in sorted(lib.glob("libegopd.so.*")) + sorted(lib.glob("*/libegopd.so.*"))
                    if p.name.count(".") == 2]
    return out + ["libegopd.so.0"]


def _load_library():
    errors = []
    for path in _library_candidates():
        try:
            lib = ctypes.CDLL(path)
            break
        except OSError as e:
            errors.append(str(e))
    else:
        raise ImportError("egopd: cannot load libegopd.so.0 (set EGOPD_LIBRARY to its path): " + "; ".join(errors))
    P, c = ctypes.POINTER, ctypes
    sig = {
        "egopd_version": (c.c_char_p, []),
        "egopd_last_error": (c.c_char_p, []),
        "egopd_load_options_init": (None, [P(_LoadOptions)]),
        "egopd_predict_options_init": (None, [P(_PredictOptions)]),
        "egopd_model_load": (c.c_int, [c.c_char_p, P(_LoadOptions), P(c.c_void_p)]),
        "egopd_model_free": (None, [c.c_void_p]),
        "egopd_model_dir": (c.c_char_p, [c.c_void_p]),
        "egopd_predict": (c.c_int, [c.c_void_p, P(_PredictOptions), P(c.c_void_p)]),
        "egopd_counterfactual": (c.c_int, [c.c_void_p, P(_PredictOptions), c.c_char_p, P(c.c_char_p), c.c_size_t,
                                           P(c.c_void_p)]),
        "egopd_result_frames": (c.c_int64, [c.c_void_p]),
        "egopd_result_size": (c.c_int64, [c.c_void_p]),
        "egopd_result_num_taxels": (c.c_int64, [c.c_void_p]),
        "egopd_result_taxels": (P(c.c_double), [c.c_void_p]),
        "egopd_result_heatmaps": (P(c.c_float), [c.c_void_p]),
        "egopd_result_total_force": (P(c.c_double), [c.c_void_p]),
        "egopd_result_contact": (P(c.c_uint8), [c.c_void_p]),
        "egopd_result_summary_json": (c.c_char_p, [c.c_void_p]),
        "egopd_result_variant_value": (c.c_char_p, [c.c_void_p]),
        "egopd_result_variant_folder": (c.c_char_p, [c.c_void_p]),
        "egopd_result_free": (None, [c.c_void_p]),
    }
    for name, (res, args) in sig.items():
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    return lib


_lib = _load_library()


def version():
    """The library's version string."""
    return _lib.egopd_version().decode()


def _raise_for(status):
    if status == OK:
        return
    msg = _lib.egopd_last_error().decode("utf-8", "replace")
    if status == ERROR_ARGUMENT:
        raise ArgumentError(msg)
    if status == CANCELLED:
        raise Cancelled(msg)
    if status == ERROR_MEMORY:
        raise MemoryError(msg)
    raise Error(msg)


def _path(p):
    return None if p is None else os.fsencode(p)


class Progress:
    """One report of a running call: stage ("encode", "denoise", "decode", "write"), step of steps (denoise), the
    step's seconds, seconds since the call started, and the counterfactual variant (1-based) of variants."""

    __slots__ = ("stage", "step", "steps", "step_seconds", "elapsed_seconds", "variant", "variants")

    def __init__(self, p):
        self.stage = p.stage.decode()
        self.step, self.steps = p.step, p.steps
        self.step_seconds, self.elapsed_seconds = p.step_seconds, p.elapsed_seconds
        self.variant, self.variants = p.variant, p.variants

    def __repr__(self):
        step = f" {self.step}/{self.steps}" if self.steps else ""
        return f"Progress({self.stage}{step}, {self.elapsed_seconds:.2f} s)"


class Result:
    """One prediction: taxels [F, 162] (N), heatmaps [F, S, S], total_force [F] (N), contact [F] (bool), summary
    (summary.json as a dict); for a counterfactual also variant (the value, e.g. "355g") and folder."""

    def __init__(self, handle):
        f = _lib.egopd_result_frames(handle)
        s = _lib.egopd_result_size(handle)
        m = _lib.egopd_result_num_taxels(handle)
        self.taxels = np.ctypeslib.as_array(_lib.egopd_result_taxels(handle), shape=(f * m,)).reshape(f, m).copy()
        self.heatmaps = np.ctypeslib.as_array(_lib.egopd_result_heatmaps(handle), shape=(f * s * s,)).reshape(
            f, s, s).copy()
        self.total_force = np.ctypeslib.as_array(_lib.egopd_result_total_force(handle), shape=(f,)).copy()
        self.contact = np.ctypeslib.as_array(_lib.egopd_result_contact(handle), shape=(f,)).astype(bool)
        self.summary = json.loads(_lib.egopd_result_summary_json(handle).decode())
        self.variant = _lib.egopd_result_variant_value(handle).decode()
        self.folder = _lib.egopd_result_variant_folder(handle).decode()

    @property
    def mean_force(self):
        return self.summary["mean_total_force_n"]

    @property
    def peak_force(self):
        return self.summary["peak_total_force_n"]

    def __repr__(self):
        return (f"Result(frames={self.taxels.shape[0]}, mean_force={self.mean_force:.2f} N"
                + (f", variant={self.variant!r}" if self.variant else "") + ")")


def _uint8_array(a, name, channels):
    a = np.asarray(a)
    if a.dtype != np.uint8:
        raise ArgumentError(f"{name}: expected a numpy uint8 array, got dtype {a.dtype}")
    if channels == 1 and a.ndim == 4 and a.shape[3] == 1:
        a = a[..., 0]
    want = 4 if channels == 3 else 3
    if a.ndim != want or (channels == 3 and a.shape[3] != 3):
        shape = "[F, H, W, 3]" if channels == 3 else "[F, H, W]"
        raise ArgumentError(f"{name}: expected an array of shape {shape}, got {list(a.shape)}")
    return np.ascontiguousarray(a)


class _Call:
    """The options, buffers and callbacks of one call, kept alive while it runs; SIGINT (Ctrl-C) becomes a
    cancellation at the next progress report and KeyboardInterrupt afterwards."""

    def __init__(self, video, frames, masks, prompt, meta, sampler, steps, seed, num_frames, size, guidance,
                 decode_chunk, out, progress):
        o = _PredictOptions()
        _lib.egopd_predict_options_init(ctypes.byref(o))
        self.keep = []
        if video is not None and frames is not None:
            raise ArgumentError("give either video or frames, not both")
        o.video = _path(video)
        if frames is not None:
            f = _uint8_array(frames, "frames", 3)
            self.keep.append(f)
            o.frames, o.frames_bytes = f.ctypes.data, f.nbytes
            o.frames_count, o.frames_height, o.frames_width = f.shape[:3]
        if isinstance(masks, (str, os.PathLike)):
            o.masks_dir = _path(masks)
        elif masks is not None:
            m = _uint8_array(masks, "masks", 1)
            self.keep.append(m)
            o.masks, o.masks_bytes = m.ctypes.data, m.nbytes
            o.masks_count, o.masks_height, o.masks_width = m.shape
        if prompt is not None:
            o.prompt = prompt.encode()
        if isinstance(meta, (str, os.PathLike)):
            o.meta_path = _path(meta)
        elif meta is not None:
            o.meta_json = json.dumps(dict(meta)).encode()
        o.sampler = sampler.encode() if sampler else None
        o.steps = steps or 0
        o.seed = seed
        o.num_frames = num_frames or 0
        o.size = size or 0
        if guidance is not None:
            lo, hi = (guidance, guidance) if np.isscalar(guidance) else guidance
            o.has_guidance, o.guidance_min, o.guidance_max = 1, float(lo), float(hi)
        o.decode_chunk = decode_chunk or 0
        o.out_dir = _path(out)
        self.user_progress = progress
        self.pending = None  # an exception raised by the callback, re-raised after the call
        self.interrupted = False
        self.callback = _PROGRESS_FN(self._on_progress)
        o.progress = self.callback
        self.options = o

    def _on_progress(self, _user, p):
        try:
            if self.interrupted:
                return 1
            if self.user_progress is not None and self.user_progress(Progress(p.contents)) is False:
                return 1
            return 0
        except BaseException as e:  # noqa: B036 - carried to the caller, never lost inside ctypes
            self.pending = e
            return 1

    def run(self, fn, *args):
        main = threading.current_thread() is threading.main_thread()
        old = None
        if main:
            def on_sigint(_sig, _frame):
                self.interrupted = True
            old = signal.signal(signal.SIGINT, on_sigint)
        try:
            status = fn(*args)
        finally:
            if main:
                signal.signal(signal.SIGINT, old)
        if self.pending is not None:
            raise self.pending
        if self.interrupted:
            raise KeyboardInterrupt("egopd: cancelled by Ctrl-C")
        _raise_for(status)


class Model:
    """A loaded model; any number of predictions run on it. path None: the built-in tiny synthetic model.
    threads None: EGOPD_THREADS, else the physical cores (process-wide). size: the frame size the model is prepared
    for (another size in a call reloads it). precision: "fp32", "bf16" or "int8", the arithmetic of the linear
    layers and convolutions in this model's calls (README, `--precision`). conv: "direct", "winograd" or "auto",
    the algorithm of its 3x3 convolutions (README, `--conv`); None: EGOPD_CONV, else "auto". log: a callable
    receiving the run's log lines (what `egopd predict` prints on stderr); None: quiet. block_cache_mb: MiB of
    freed activation blocks kept for reuse in its calls (README, `--block-cache-mb`); None: EGOPD_BLOCK_CACHE_MB,
    else 1024; 0: none. The cached blocks are given back when the last Model is closed."""

    def __init__(self, path=None, threads=None, low_mem=False, size=256, template=None, precision="fp32", log=None,
                 conv=None, block_cache_mb=None):
        o = _LoadOptions()
        _lib.egopd_load_options_init(ctypes.byref(o))
        o.threads = threads or 0
        o.low_mem = 1 if low_mem else 0
        o.precision = precision.encode() if precision else None
        o.conv = conv.encode() if conv else None
        o.block_cache_mb = -1 if block_cache_mb is None else block_cache_mb
        o.size = size
        o.template_path = _path(template)
        self._log = _LOG_FN(lambda _u, line: log(line.decode("utf-8", "replace"))) if log else _LOG_FN()
        o.log = self._log
        self._handle = ctypes.c_void_p()
        _raise_for(_lib.egopd_model_load(_path(path), ctypes.byref(o), ctypes.byref(self._handle)))

    @property
    def path(self):
        """The model folder (for the built-in model: its cache folder)."""
        return _lib.egopd_model_dir(self._handle).decode()

    def close(self):
        if getattr(self, "_handle", None):
            _lib.egopd_model_free(self._handle)
            self._handle = None

    def __del__(self):
        self.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _check(self):
        if not self._handle:
            raise Error("the model was closed")

    def predict(self, video=None, frames=None, masks=None, prompt=None, meta=None, sampler=None, steps=None, seed=0,
                num_frames=None, size=None, guidance=None, decode_chunk=None, out=None, progress=None):
        """One prediction. video: a clip file or frame folder; frames: uint8 [F, H, W, 3] RGB (neither: the built-in
        sample clip). masks: a folder or uint8 [M, H, W] (> 127 = hand). prompt: verbatim text; meta: a dict of
        prompt fields (obj_name, weight, material, gender, age, subj_weight, bodyfat) or a META.json path.
        sampler "euler"/"lcm", steps, seed, num_frames (16), size, guidance (a number or (min, max)), decode_chunk:
        as `egopd predict`. out: also write the output folder. progress: callable(Progress); False cancels."""
        self._check()
        call = _Call(video, frames, masks, prompt, meta, sampler, steps, seed, num_frames, size, guidance,
                     decode_chunk, out, progress)
        handle = ctypes.c_void_p()
        call.run(_lib.egopd_predict, self._handle, ctypes.byref(call.options), ctypes.byref(handle))
        try:
            return Result(handle)
        finally:
            _lib.egopd_result_free(handle)

    def counterfactual(self, vary, video=None, frames=None, masks=None, meta=None, sampler=None, steps=None, seed=0,
                       num_frames=None, size=None, guidance=None, decode_chunk=None, out=None, progress=None):
        """The same clip and seed under every value of one prompt field: vary is "FIELD=v1,v2,..." (as
        `egopd counterfactual --vary`) or (field, [values]); a bare number gets the field's unit, "omit" drops the
        field; the other fields come from meta. Encodes the clip once. Returns one Result per value."""
        self._check()
        if isinstance(vary, str):
            field, _, values = vary.partition("=")
            values = values.split(",") if values else []
        else:
            field, values = vary
            values = [str(v) for v in values]
        call = _Call(video, frames, masks, None, meta, sampler, steps, seed, num_frames, size, guidance,
                     decode_chunk, out, progress)
        arr = (ctypes.c_char_p * max(1, len(values)))(*[v.encode() for v in values])
        handles = (ctypes.c_void_p * max(1, len(values)))()
        call.run(_lib.egopd_counterfactual, self._handle, ctypes.byref(call.options), field.encode(), arr,
                 len(values), handles)
        try:
            return [Result(h) for h in handles[:len(values)]]
        finally:
            for h in handles[:len(values)]:
                _lib.egopd_result_free(h)
