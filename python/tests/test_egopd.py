"""Tests of the Python module on the built-in tiny synthetic model at 64 x 64 (pytest or unittest).

Expected taxels come from the egopd command (EGOPD_CLI, else `egopd` on PATH) for the same inputs and seed: its
taxels.csv parsed to float64 must equal the module's array bit for bit, and a folder written by the module holds the
same taxels.csv bytes. Frames and masks given as numpy arrays are compared with the command reading the same
pixels from BMP files.
"""
import os
import shutil
import signal
import struct
import subprocess
import tempfile
import unittest

import numpy as np

WORK = tempfile.mkdtemp(prefix="egopd_py_test_")
os.environ["XDG_CACHE_HOME"] = os.path.join(WORK, "cache")  # the built-in model, shared with the command

import egopd  # noqa: E402

CLI = os.environ.get("EGOPD_CLI") or shutil.which("egopd") or "egopd"
COMMON = ["--frames", "2", "--size", "64", "--threads", "2"]


def cli(*args):
    r = subprocess.run([CLI, *args], capture_output=True, text=True)
    if r.returncode != 0:
        raise AssertionError(f"egopd {' '.join(args)} failed ({r.returncode}): {r.stderr}")
    return r


def cli_csv(*args):
    out = os.path.join(WORK, "cli_%d" % len(os.listdir(WORK)))
    cli("predict", *COMMON, *args, "--out", out)
    return os.path.join(out, "taxels.csv")


def read_csv(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
        rows = [[float(v) for v in line.strip().split(",")[1:]] for line in f if line.strip()]
    assert header[0] == "frame" and len(header) == 163, header
    return np.array(rows, dtype=np.float64)


def write_bmp(path, img):
    """24-bit BMP (what the command reads back to the same pixels); img uint8 [H, W, 3] RGB or [H, W] grey."""
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    h, w, _ = img.shape
    row = (w * 3 + 3) & ~3
    data = bytearray()
    for y in range(h - 1, -1, -1):  # bottom-up, BGR, rows padded to 4 bytes
        data += img[y, :, ::-1].tobytes() + b"\0" * (row - w * 3)
    header = struct.pack("<2sIHHI", b"BM", 54 + len(data), 0, 0, 54)
    info = struct.pack("<IiiHHIIiiII", 40, w, h, 1, 24, 0, len(data), 2835, 2835, 0, 0)
    with open(path, "wb") as f:
        f.write(header + info + data)


def clip_arrays():
    """5 frames of 80 x 96 (not square: the squash is tested too) and 5 hint masks."""
    y, x = np.mgrid[0:80, 0:96]
    frames, masks = [], []
    for t in range(5):
        r = (x * 2 + t * 20) % 256
        g = (y * 3 + t * 7) % 256
        b = ((x + y) * (t + 1)) % 256
        frames.append(np.stack([r, g, b], axis=2).astype(np.uint8))
        masks.append((((x - 40 - 3 * t) ** 2 + (y - 45) ** 2) < 30 ** 2).astype(np.uint8) * 255)
    return np.stack(frames), np.stack(masks)


class ModuleTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.model = egopd.Model(size=64, threads=2)  # the built-in model, created in the cache once

    @classmethod
    def tearDownClass(cls):
        cls.model.close()

    def assert_same_taxels(self, result, csv_path):
        want = read_csv(csv_path)
        self.assertEqual(result.taxels.shape, want.shape)
        self.assertEqual(result.taxels.tobytes(), want.tobytes())

    def test_builtin_model_and_clip_match_the_command(self):
        r = self.model.predict(num_frames=2, seed=0)
        self.assert_same_taxels(r, cli_csv())
        self.assertEqual(r.heatmaps.shape, (2, 64, 64))
        self.assertEqual(r.summary["frames"], 2)
        self.assertTrue(r.summary["model_synthetic"])
        self.assertEqual(list(r.total_force), [sum(row) for row in r.taxels.tolist()])  # summed in frame order

    def test_frames_and_masks_from_numpy_match_the_command(self):
        frames, masks = clip_arrays()
        fdir, mdir = os.path.join(WORK, "frames"), os.path.join(WORK, "masks")
        os.makedirs(fdir, exist_ok=True)
        os.makedirs(mdir, exist_ok=True)
        for i in range(5):
            write_bmp(os.path.join(fdir, "%05d.bmp" % i), frames[i])
            write_bmp(os.path.join(mdir, "%05d.bmp" % i), masks[i])
        r = self.model.predict(frames=frames, masks=masks, num_frames=3, seed=4, prompt="a hand holding a cup")
        self.assert_same_taxels(r, cli_csv("--video", fdir, "--masks", mdir, "--seed", "4",
                                           "--prompt", "a hand holding a cup", "--frames", "3"))
        self.assertEqual(r.taxels.shape, (3, 162))

    def test_output_folder_holds_the_command_bytes(self):
        out = os.path.join(WORK, "py_out")
        r = self.model.predict(num_frames=2, seed=9, meta={"obj_name": "a CocaCola", "weight": 355}, out=out)
        meta = os.path.join(WORK, "meta.json")
        with open(meta, "w") as f:
            f.write('{"obj_name": "a CocaCola", "weight": 355}')
        with open(os.path.join(out, "taxels.csv"), "rb") as a, open(cli_csv("--seed", "9", "--meta", meta), "rb") as b:
            self.assertEqual(a.read(), b.read())
        self.assertTrue(os.path.exists(os.path.join(out, "heatmap_001.png")))
        self.assertIn("CocaCola", r.summary["prompt"])

    def test_counterfactual_matches_the_command(self):
        meta = os.path.join(WORK, "meta_cf.json")
        with open(meta, "w") as f:
            f.write('{"obj_name": "a CocaCola", "weight": 355, "material": "aluminum"}')
        results = self.model.counterfactual("weight=1000,omit", meta=meta, num_frames=2, seed=2)
        out = os.path.join(WORK, "cli_cf")
        cli("counterfactual", *COMMON, "--meta", meta, "--seed", "2", "--vary", "weight=1000,omit", "--out", out)
        self.assertEqual([r.folder for r in results], ["weight_1000g", "weight_omit"])
        for r in results:
            self.assert_same_taxels(r, os.path.join(out, r.folder, "taxels.csv"))
        same = self.model.counterfactual(("weight", [1000]), meta={"obj_name": "a CocaCola", "weight": 355,
                                                                    "material": "aluminum"}, num_frames=2, seed=2)
        self.assertEqual(same[0].taxels.tobytes(), results[0].taxels.tobytes())

    def test_bad_input_raises_one_line_errors(self):
        cases = [
            (dict(frames=np.zeros((2, 8, 8, 3), np.float32)), egopd.ArgumentError, "frames: expected a numpy uint8"),
            (dict(frames=np.zeros((2, 8, 8), np.uint8)), egopd.ArgumentError, "frames: expected an array of shape"),
            (dict(frames=np.zeros((0, 8, 8, 3), np.uint8)), egopd.ArgumentError, "frames: count, height and width"),
            (dict(steps=5000), egopd.ArgumentError, "--steps must be between 1 and 1000"),
            (dict(video="/nonexistent/clip.mp4"), egopd.ArgumentError, "/nonexistent/clip.mp4"),
            (dict(prompt="x", meta={"weight": 3}), egopd.ArgumentError, "either --prompt or --meta"),
            (dict(meta={"weight": [1, 2]}), egopd.Error, "weight"),
            (dict(sampler="ddim"), egopd.ArgumentError, "--sampler must be euler or lcm"),
        ]
        for kwargs, exc, needle in cases:
            with self.subTest(kwargs=list(kwargs)):
                with self.assertRaises(exc) as cm:
                    self.model.predict(num_frames=2, **kwargs)
                msg = str(cm.exception)
                self.assertNotIn("\n", msg)
                if needle:
                    self.assertIn(needle, msg)
        with self.assertRaisesRegex(egopd.ArgumentError, "expected fp32, bf16 or int8"):
            egopd.Model(precision="fp16")
        with self.assertRaisesRegex(egopd.ArgumentError, "conv 'fft': expected direct, winograd or auto"):
            egopd.Model(conv="fft")
        with self.assertRaisesRegex(egopd.ArgumentError, "--block-cache-mb must be between 0 and 1048576"):
            egopd.Model(block_cache_mb=-7)
        with self.assertRaisesRegex(egopd.Error, "/nonexistent/model"):
            egopd.Model("/nonexistent/model")
        self.assertEqual(self.model.predict(num_frames=2).taxels.shape, (2, 162))  # still usable

    def test_progress_reports_and_cancels(self):
        seen = []
        first = self.model.predict(num_frames=2, seed=1, progress=lambda p: seen.append((p.stage, p.step)))
        self.assertEqual([s for s, _ in seen], ["encode", "denoise", "denoise", "denoise", "denoise", "decode"])
        with self.assertRaisesRegex(egopd.Cancelled, "cancelled by the progress callback at denoise step 2 of 4"):
            self.model.predict(num_frames=2, seed=1, progress=lambda p: not (p.stage == "denoise" and p.step == 2))

        def boom(p):
            raise ValueError("stop here")

        with self.assertRaisesRegex(ValueError, "stop here"):
            self.model.predict(num_frames=2, seed=1, progress=boom)
        again = self.model.predict(num_frames=2, seed=1)
        self.assertEqual(again.taxels.tobytes(), first.taxels.tobytes())

    def test_ctrl_c_cancels_and_the_model_stays_usable(self):
        def interrupt(p):
            if p.stage == "denoise" and p.step == 1:
                os.kill(os.getpid(), signal.SIGINT)

        out = os.path.join(WORK, "interrupted")
        # Python's handler, or SIG_IGN when the tests were started in the background (nohup, `&` without job
        # control): whichever it was, the call puts it back.
        before = signal.getsignal(signal.SIGINT)
        with self.assertRaises(KeyboardInterrupt):
            self.model.predict(num_frames=2, seed=1, progress=interrupt, out=out)
        self.assertFalse(os.path.exists(out))
        self.assertIs(signal.getsignal(signal.SIGINT), before)
        self.assertEqual(self.model.predict(num_frames=2, seed=1).taxels.shape, (2, 162))

    def test_version(self):
        self.assertRegex(egopd.version(), r"^\d+\.\d+\.\d+$")


if __name__ == "__main__":
    unittest.main()
