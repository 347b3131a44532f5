"""The Python module vtsim (docs/python.md), against the build tree's module and CLI.

Run by the ctest python_module (label python):
    PYTHONPATH=build/python VTSIM_CLI=build/vtsim /usr/bin/python3 tests/python/test_vtsim.py
Each replay is a 2-second walk at view.divisor 8 (~0.1 s of CPU).
"""
import concurrent.futures
import csv
import json
import math
import os
import pathlib
import subprocess
import sys
import tempfile
import threading
import unittest

import numpy as np

import vtsim

CLI = os.environ.get("VTSIM_CLI", "")
SETS = ["view.divisor=8"]


def strip_run(summary):
    """A summary without the run's own cost (wall time, RSS) and the build's commit (the module and
    the CLI may be linked at different commits of a build tree): what two replays of one config share."""
    s = dict(summary)
    s.pop("run", None)
    s["provenance"] = {k: v for k, v in s["provenance"].items() if k != "vtsim_commit"}
    return s


def cli(*args):
    return subprocess.run([CLI, *args], check=True, capture_output=True, text=True).stdout


class VtsimTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not CLI:
            raise unittest.SkipTest("VTSIM_CLI names no vtsim executable")
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dir = pathlib.Path(cls.tmp.name)
        cls.trace = str(cls.dir / "walk.csv")
        cli("trace", "gen", "walk", "--duration", "2", "-o", cls.trace)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_replay_equals_cli_summary_and_frames(self):
        r = vtsim.replay(trace=self.trace, sets=SETS)
        summary_file, frames_file = self.dir / "cli.json", self.dir / "cli_frames.csv"
        cli("replay", "--trace", self.trace, "--set", SETS[0], "-q", "--summary", str(summary_file),
            "--frames", str(frames_file))
        self.assertEqual(strip_run(r["summary"]), strip_run(json.loads(summary_file.read_text())))
        with open(frames_file, newline="") as f:
            rows = list(csv.DictReader(f))
        frames = r["frames"]
        self.assertEqual(list(frames.keys()), list(rows[0].keys()))
        self.assertEqual(len(rows), len(frames["frame"]))
        self.assertEqual(len(rows), r["summary"]["trace"]["frames"])
        for name, col in frames.items():
            self.assertIsInstance(col, np.ndarray, name)
            want = np.array([float(row[name]) for row in rows])
            # The CSV prints t_s and the fractions with 6 decimals; everything else exactly.
            np.testing.assert_allclose(col.astype(np.float64), want, rtol=0, atol=5e-7, err_msg=name)
        self.assertTrue(frames["blurry_fraction"].max() > 0, "the walk sees the texture: pop-in was measured")
        self.assertEqual(frames["measured"].dtype, np.bool_)
        self.assertEqual(frames["disk_bytes"].dtype, np.uint64)
        self.assertEqual(int(frames["disk_bytes"].sum()), r["summary"]["bandwidth"]["disk_read_bytes"])

    def test_config_dict_file_and_sets_agree(self):
        by_sets = vtsim.replay(trace=self.trace, sets=SETS + ["upload.tiles_per_frame=4"])
        by_dict = vtsim.replay(trace=self.trace, config={"view": {"divisor": 8}, "upload.tiles_per_frame": 4})
        toml = self.dir / "c.toml"
        toml.write_text("[view]\ndivisor = 8\n[upload]\ntiles_per_frame = 4\n")
        by_file = vtsim.replay(trace=pathlib.Path(self.trace), config=toml)
        self.assertEqual(strip_run(by_sets["summary"]), strip_run(by_dict["summary"]))
        self.assertEqual(strip_run(by_sets["summary"]), strip_run(by_file["summary"]))
        self.assertEqual(by_dict["summary"]["config"]["upload.tiles_per_frame"], 4)
        default = vtsim.replay(trace=self.trace, sets=SETS)
        self.assertNotEqual(strip_run(default["summary"]), strip_run(by_dict["summary"]))

    def test_bad_input_names_the_key(self):
        with self.assertRaises(KeyError) as e:
            vtsim.replay(trace=self.trace, config={"view": {"divisr": 8}})
        self.assertIn("view.divisr", str(e.exception))
        self.assertIn("view.divisor", str(e.exception))  # the suggestion
        self.assertIsInstance(e.exception, vtsim.ConfigKeyError)
        self.assertIsInstance(e.exception, vtsim.InputError)
        with self.assertRaises(KeyError) as e:
            vtsim.replay(trace=self.trace, sets=["nosuch.key=1"])
        self.assertIn("nosuch.key", str(e.exception))
        with self.assertRaises(ValueError) as e:
            vtsim.replay(trace=self.trace, config={"view.divisor": "eight"})
        self.assertIn("view.divisor", str(e.exception))
        self.assertNotIsInstance(e.exception, KeyError)
        with self.assertRaises(ValueError) as e:
            vtsim.replay(trace=self.trace, config={"view.divisor": [8]})
        self.assertIn("view.divisor", str(e.exception))
        self.assertIn("list", str(e.exception))
        with self.assertRaises(ValueError) as e:
            vtsim.replay(trace=self.trace, config={"view.divisor": 0})
        self.assertIn("view.divisor", str(e.exception))
        with self.assertRaises(ValueError) as e:
            vtsim.replay(trace=5)
        self.assertEqual(e.exception.where, "trace")
        with self.assertRaises(ValueError) as e:
            vtsim.replay(trace=self.trace, sets="view.divisor")  # no '='
        self.assertIn("view.divisor", str(e.exception))
        missing = str(self.dir / "missing.csv")
        with self.assertRaises(vtsim.InputError) as e:
            vtsim.replay(trace=missing)
        self.assertIn(missing, str(e.exception))
        bad = self.dir / "bad.toml"
        bad.write_text("[view]\n\ndivisor = -3\n")
        with self.assertRaises(ValueError) as e:
            vtsim.replay(trace=self.trace, config=str(bad))
        self.assertIn(f"{bad}:3", str(e.exception))  # file:line
        self.assertIn("view.divisor", str(e.exception))
        with self.assertRaises(ValueError):
            vtsim.replay(trace=self.trace, feedback=self.trace)  # one of them

    def test_load_trace(self):
        t = vtsim.load_trace(self.trace)
        n = 121  # 2 s at 60 frames/s, both ends
        self.assertEqual(t["pos_m"].shape, (n, 3))
        self.assertEqual(t["q_wxyz"].shape, (n, 4))
        self.assertEqual(t["t_s"].shape, (n,))
        self.assertTrue(np.all(np.diff(t["t_s"]) > 0))
        np.testing.assert_allclose(np.linalg.norm(t["q_wxyz"], axis=1), 1.0, atol=1e-9)
        self.assertEqual((t["image_width"], t["image_height"]), (1920, 1080))
        # The walk goes east at 1.5 m/s from (4096, 4096).
        self.assertAlmostEqual(t["pos_m"][-1, 0] - t["pos_m"][0, 0], 3.0, places=6)
        with self.assertRaises(vtsim.InputError):
            vtsim.load_trace(str(self.dir / "missing.csv"))

    @classmethod
    def sweep_rows(cls):
        if not hasattr(cls, "_rows"):
            cls.spec = cls.dir / "sweep.toml"
            cls.spec.write_text(f'set = ["view.divisor=8"]\ntraces = ["{cls.trace}"]\n'
                                'metrics = ["popin.blurry_fraction_mean", "latency_ms.p99", "bandwidth.disk_reads"]\n'
                                '[grid]\n"upload.tiles_per_frame" = [4, 8]\n"ram.policy" = ["lru", "clock"]\n')
            cls._rows = vtsim.sweep(str(cls.spec), jobs=2)
        return cls._rows

    def test_sweep_rows(self):
        rows = self.sweep_rows()
        self.assertEqual(len(rows), 4)
        for r in rows:
            for k, v in r.items():
                self.assertTrue(v is None or isinstance(v, (int, float, str, bool)), f"{k}: {type(v)}")
            self.assertEqual(r["status"], "ok")
            self.assertIsNone(r["error"])
        self.assertEqual([r["upload.tiles_per_frame"] for r in rows], [4, 4, 8, 8])
        self.assertEqual([r["ram.policy"] for r in rows], ["lru", "clock", "lru", "clock"])
        # A row is the replay of its config alone.
        one = vtsim.replay(trace=self.trace, sets=SETS + ["upload.tiles_per_frame=8", "ram.policy=clock"])
        self.assertEqual(rows[3]["popin.blurry_fraction_mean"], one["summary"]["popin"]["blurry_fraction_mean"])
        self.assertEqual(rows[3]["bandwidth.disk_reads"], one["summary"]["bandwidth"]["disk_reads"])
        with self.assertRaises(vtsim.InputError) as e:
            vtsim.sweep(str(self.spec), metrics=["popin.no_such_metric"])
        self.assertIn("popin.no_such_metric", str(e.exception))

    def test_sweep_rows_make_a_dataframe(self):
        try:
            import pandas
        except ImportError:
            self.skipTest("pandas is not installed (Debian: python3-pandas)")
        rows = self.sweep_rows()
        df = pandas.DataFrame(rows)
        self.assertEqual(len(df), 4)
        self.assertEqual(str(df["upload.tiles_per_frame"].dtype), "int64")
        self.assertEqual(str(df["popin.blurry_fraction_mean"].dtype), "float64")
        self.assertEqual(str(df["bandwidth.disk_reads"].dtype), "int64")
        self.assertEqual(str(df["ram.policy"].dtype), "object")
        self.assertEqual(df.groupby("ram.policy")["bandwidth.disk_reads"].count().to_dict(), {"clock": 2, "lru": 2})

    def test_capacity_equals_cli(self):
        sets = ["texture.width=65536", "texture.height=32768", "clipmap.clipsize=512"]
        set_args = [a for s in sets for a in ("--set", s)]
        c = vtsim.capacity(sets=sets)
        j = json.loads(cli("capacity", *set_args, "--json"))
        for k in ("levels", "stack_levels", "pyramid_levels", "stack_texels", "pyramid_texels", "full_mip_texels",
                  "clipmap_bytes", "full_mip_bytes"):
            self.assertEqual(c[k], j[k], k)
        v = vtsim.capacity(sets=sets, system="vt", screen=(1280, 720), overdraw=2.0)
        j = json.loads(cli("capacity", "--system", "vt", *set_args, "--screen", "1280x720", "--overdraw", "2", "--json"))
        for k in ("levels", "pages", "pages_level0", "disk_bytes", "decoded_bytes"):
            self.assertEqual(v[k], j[k], k)
        self.assertEqual(v["pool_pages"], j["pool"]["pages"])
        self.assertEqual(v["page_table_bytes"], j["page_table"]["bytes"])
        with self.assertRaises(ValueError) as e:
            vtsim.capacity(system="vt", screen="1280x720")
        self.assertEqual(e.exception.where, "screen")

    def test_mrc_equals_cli(self):
        acc = self.dir / "acc.txt"
        keys = [(i * 7919) % 97 for i in range(2000)] + list(range(50))
        acc.write_text("".join(f"{k}\n" for k in keys))
        m = vtsim.mrc(accesses=str(acc), sizes=9, opt=True)
        j = json.loads(cli("mrc", "--accesses", str(acc), "--sizes", "9", "--opt", "--json"))
        self.assertEqual(list(m["capacity"]), [p["capacity"] for p in j["curve"]])
        self.assertEqual(list(m["miss_ratio"]), [p["miss_ratio"] for p in j["curve"]])
        self.assertEqual(list(m["belady_miss_ratio"]), [p["belady_miss_ratio"] for p in j["curve"]])
        self.assertEqual((m["accesses"], m["keys"]), (j["accesses"], j["keys"]))
        self.assertEqual(m["knee"], j["knee"])
        with self.assertRaises(ValueError) as e:
            vtsim.mrc(accesses=str(acc), sizes=1)
        self.assertEqual(e.exception.where, "sizes")
        r = vtsim.mrc(trace=self.trace, sets=SETS + ["run.system=vt"], sizes=5)
        self.assertEqual(r["unit"], "pages")
        self.assertGreater(r["accesses"], 0)

    def test_threads_equal_serial(self):
        configs = [SETS + ["upload.tiles_per_frame=4"], SETS + ["upload.tiles_per_frame=16", "run.system=vt"]]
        serial = [strip_run(vtsim.replay(trace=self.trace, sets=s)["summary"]) for s in configs]
        self.assertNotEqual(serial[0], serial[1])
        with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
            threaded = list(pool.map(lambda s: strip_run(vtsim.replay(trace=self.trace, sets=s)["summary"]), configs * 2))
        self.assertEqual(threaded, serial * 2)

    def test_gil_released_during_replay(self):
        # A probe thread counts while the main thread is inside vtsim.replay. The switch interval is
        # set far beyond the test's length, so the main thread never hands the GIL over on its own:
        # between reading `before` and `after` the probe can run only if replay released the GIL.
        # Were it held, the count would not move during any replay and the test would fail.
        count = [0]
        ready, done = threading.Event(), threading.Event()

        def probe():
            while not done.is_set():
                count[0] += 1
                ready.set()
                done.wait(0.0005)  # blocks: releases the GIL, then wants it back

        old = sys.getswitchinterval()
        sys.setswitchinterval(1000.0)
        t = threading.Thread(target=probe)
        try:
            t.start()
            ready.wait()
            moved = []
            for _ in range(5):  # a replay takes ~50 ms; the probe wakes every 0.5 ms
                before = count[0]
                vtsim.replay(trace=self.trace, sets=SETS)
                after = count[0]
                moved.append(after - before)
                if after > before:
                    break
        finally:
            done.set()
            t.join()
            sys.setswitchinterval(old)
        self.assertGreater(max(moved), 0, f"the probe never ran during a replay: {moved}")


if __name__ == "__main__":
    unittest.main(verbosity=2)
