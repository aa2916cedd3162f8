# The add-on's runner (tools/blender/snowmodel_addon/runner.py) without
# Blender: the command line it builds, the progress it reads and where it
# looks for the binary. Run by ctest as test_blender_runner.
import os
import stat
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "tools", "blender",
                                "snowmodel_addon"))
import runner  # noqa: E402

SETTINGS = {"depth": 0.3, "snow": "fresh", "wind_speed": 0.0, "wind_heading": 0.0,
            "texel": 0.0, "max_side": 0, "directions": 64, "no_snow_on": "", "ignore": ""}


def option(args, name):
    return args[args.index(name) + 1]


class Command(unittest.TestCase):
    def test_wind_turns_from_blenders_z_up_to_gltfs_y_up(self):
        # Blender +Y (heading 90) is glTF -Z; +X stays +X.
        args = runner.command("snowmodel", "in.glb", "out.glb",
                              dict(SETTINGS, wind_speed=6.0, wind_heading=90.0))
        x, z = (float(v) for v in option(args, "--wind").split(","))
        self.assertAlmostEqual(x, 0.0, places=5)
        self.assertAlmostEqual(z, -6.0, places=5)
        args = runner.command("snowmodel", "in.glb", "out.glb",
                              dict(SETTINGS, wind_speed=6.0, wind_heading=0.0))
        self.assertEqual(option(args, "--wind"), "6,0")

    def test_snow_only_into_the_output_with_the_settings(self):
        args = runner.command("snowmodel", "in.glb", "out.glb",
                              dict(SETTINGS, depth=0.5, snow="wet", directions=16))
        self.assertEqual(args[:5], ["snowmodel", "snow", "in.glb", "-o", "out.glb"])
        self.assertIn("--snow-only", args)
        self.assertEqual(option(args, "--depth"), "0.5")
        self.assertEqual(option(args, "--snow"), "wet")
        self.assertEqual(option(args, "--directions"), "16")
        self.assertNotIn("--texel", args)
        self.assertNotIn("--max-side", args)

    def test_texel_before_max_side_and_globs_one_option_each(self):
        args = runner.command("snowmodel", "in.glb", "out.glb",
                              dict(SETTINGS, texel=0.02, max_side=512,
                                   no_snow_on="Glass*, Car", ignore=" Sky "))
        self.assertEqual(option(args, "--texel"), "0.02")
        self.assertNotIn("--max-side", args)
        pairs = list(zip(args, args[1:]))
        self.assertIn(("--no-snow-on", "Glass*"), pairs)
        self.assertIn(("--no-snow-on", "Car"), pairs)
        self.assertIn(("--ignore", "Sky"), pairs)


class Progress(unittest.TestCase):
    def test_stages_make_one_rising_bar(self):
        state = {}
        shares = [runner.progress_of(line, state) for line in
                  ("coverage: 50%", "coverage:    done in 2.16 s", "snowfall: 12%",
                   "warning: something", "snowfall: 100%", "export:      done in 0.01 s")]
        self.assertIsNone(shares[3])
        values = [s[0] for s in shares if s]
        self.assertEqual(values, sorted(values))
        self.assertEqual(shares[2][1], "snowfall")
        self.assertAlmostEqual(values[-1], 1.0)

    def test_the_error_line_is_reported(self):
        self.assertEqual(runner.last_error(["load: 10%", "error: x.glb: not a glTF file"]),
                         "x.glb: not a glTF file")
        self.assertEqual(runner.last_error(["something odd"]), "something odd")


class Running(unittest.TestCase):
    def test_output_is_collected_and_cancel_stops_the_whole_group(self):
        import time
        run = runner.Run(["sh", "-c", "echo 'coverage: 50%'; sleep 30 & wait"])
        lines = []
        for _ in range(100):
            new, status = run.poll()
            lines += new
            if lines:
                break
            time.sleep(0.05)
        self.assertEqual(lines, ["coverage: 50%"])
        self.assertIsNone(status)
        run.cancel()
        _, status = run.poll()
        self.assertIsNotNone(status)

    def test_exit_status_and_error_line(self):
        run = runner.Run(["sh", "-c", "echo 'error: bad.glb: not a glTF file' >&2; exit 2"])
        self.assertEqual(run.wait(), 2)
        self.assertEqual(runner.last_error(run.lines), "bad.glb: not a glTF file")

    def test_a_binary_that_cannot_run_is_a_clear_error(self):
        with self.assertRaisesRegex(runner.SnowmodelError, "cannot run /nonexistent"):
            runner.Run(["/nonexistent/snowmodel"])


class FindBinary(unittest.TestCase):
    def setUp(self):
        self.saved = dict(os.environ)

    def tearDown(self):
        os.environ.clear()
        os.environ.update(self.saved)

    def test_preference_then_environment_then_path(self):
        with tempfile.TemporaryDirectory() as d:
            exe = os.path.join(d, "snowmodel")
            with open(exe, "w") as f:
                f.write("#!/bin/sh\n")
            os.chmod(exe, stat.S_IRWXU)
            os.environ["PATH"] = d
            os.environ.pop("SNOWMODEL_BIN", None)
            self.assertEqual(runner.find_binary(""), exe)
            os.environ["SNOWMODEL_BIN"] = exe
            self.assertEqual(runner.find_binary(""), exe)
            with self.assertRaisesRegex(runner.SnowmodelError, "not found at /nope"):
                runner.find_binary("/nope")
            os.environ["SNOWMODEL_BIN"] = "/missing"
            with self.assertRaisesRegex(runner.SnowmodelError, "SNOWMODEL_BIN"):
                runner.find_binary("")
            os.environ.pop("SNOWMODEL_BIN")
            os.environ["PATH"] = tempfile.gettempdir() + "/no-such-dir"
            with self.assertRaisesRegex(runner.SnowmodelError, "add-on preferences"):
                runner.find_binary("")


if __name__ == "__main__":
    unittest.main()
