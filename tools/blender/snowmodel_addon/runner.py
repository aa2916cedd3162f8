# Running the snowmodel binary: finding it, its command line, and its
# progress lines. Plain Python (no bpy), so it is tested without Blender too.
import os
import re
import shutil
import signal
import subprocess
import threading
import queue

# snowmodel prints "STAGE: NN%" while a stage runs and "STAGE: done in S s"
# when it ends (stderr); the stages in the order a run passes them, with the
# share of a typical run each takes, for one progress bar over the run.
STAGES = (("load", 0.05), ("peel", 0.15), ("coverage", 0.2), ("snowfall", 0.4),
          ("polygonize", 0.15), ("export", 0.05))
_PROGRESS = re.compile(r"^(\w+):\s+(\d+)%")
_DONE = re.compile(r"^(\w+):\s+done in")


def restore_numpy_bool():
    """Blender 3.4's glTF importer uses numpy's `numpy.bool` alias, which
    numpy 1.24 removed (Debian's Blender with Debian's numpy): restores it.
    Returns False where numpy is missing (Debian's blender package does not
    pull it in: python3-numpy)."""
    try:
        import warnings

        import numpy
    except ImportError:
        return False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numpy 1.24 warns when asked for .bool
        if not hasattr(numpy, "bool"):
            numpy.bool = numpy.bool_
    return True


class SnowmodelError(Exception):
    """A problem the user can fix, with a one-line message."""


def find_binary(preference=""):
    """The snowmodel executable: the add-on preference, then $SNOWMODEL_BIN,
    then PATH. Raises SnowmodelError naming where it looked."""
    for where, path in (("the add-on preferences", preference),
                        ("SNOWMODEL_BIN", os.environ.get("SNOWMODEL_BIN", ""))):
        if path:
            path = os.path.expanduser(path)
            if os.path.isfile(path) and os.access(path, os.X_OK):
                return path
            raise SnowmodelError(f"snowmodel not found at {path} (set in {where})")
    found = shutil.which("snowmodel")
    if found:
        return found
    raise SnowmodelError("snowmodel not found: set its path in the add-on preferences, "
                         "in SNOWMODEL_BIN, or put it on PATH")


def command(binary, scene_glb, snow_glb, settings):
    """The command line that snows scene_glb into snow_glb (the snow only).
    settings: depth (m), snow ("powder", "fresh", "wet"), wind_speed (m/s),
    wind_heading (degrees in Blender's XY plane, from +X towards +Y, where
    the wind blows to), texel (m, 0 = automatic), max_side (0 = automatic),
    directions, no_snow_on and ignore (comma-separated name globs)."""
    import math
    a = math.radians(settings["wind_heading"])
    speed = settings["wind_speed"]
    # Blender (x, y, z), Z up -> glTF (x, z, -y), Y up.
    wind_x, wind_z = speed * math.cos(a) + 0.0, -speed * math.sin(a) + 0.0  # no "-0"
    args = [binary, "snow", scene_glb, "-o", snow_glb, "--snow-only",
            "--depth", f"{settings['depth']:g}", "--snow", settings["snow"],
            "--wind", f"{wind_x:.6g},{wind_z:.6g}",
            "--directions", str(settings["directions"])]
    if settings["texel"] > 0:
        args += ["--texel", f"{settings['texel']:g}"]
    elif settings["max_side"] > 0:
        args += ["--max-side", str(settings["max_side"])]
    for option, globs in (("--no-snow-on", settings["no_snow_on"]),
                          ("--ignore", settings["ignore"])):
        for glob in (g.strip() for g in globs.split(",")):
            if glob:
                args += [option, glob]
    return args


def progress_of(line, state):
    """Reads one output line; returns (share of the run done 0..1, stage)
    or None when the line says nothing about progress. `state` is a dict
    kept between calls."""
    line = line.strip()
    m = _PROGRESS.match(line) or _DONE.match(line)
    if not m:
        return None
    stage = m.group(1)
    names = [s for s, _ in STAGES]
    if stage not in names:
        return None
    i = names.index(stage)
    within = 1.0 if _DONE.match(line) else int(m.group(2)) / 100.0
    done = sum(w for _, w in STAGES[:i]) + STAGES[i][1] * within
    state["done"] = max(state.get("done", 0.0), done)
    return state["done"], stage


def last_error(lines):
    """snowmodel's one-line error ("error: ..."), else its last line."""
    for line in reversed(lines):
        if line.startswith("error:"):
            return line[len("error:"):].strip()
    return lines[-1].strip() if lines else "snowmodel failed without a message"


class Run:
    """snowmodel running in the background; its output lines are collected
    by a thread, so polling never blocks Blender's interface."""

    def __init__(self, args):
        self.lines = []
        self._queue = queue.Queue()
        try:
            # Its own process group, so cancelling stops what it started too.
            self._process = subprocess.Popen(args, stdout=subprocess.PIPE,
                                             stderr=subprocess.STDOUT, text=True, bufsize=1,
                                             start_new_session=True)
        except OSError as e:
            raise SnowmodelError(f"cannot run {args[0]}: {e.strerror}") from e
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self):
        for line in self._process.stdout:
            self._queue.put(line.rstrip("\n"))
        self._queue.put(None)

    def poll(self):
        """New output lines since the last call, and the exit status (None
        while it runs)."""
        new = []
        while True:
            try:
                line = self._queue.get_nowait()
            except queue.Empty:
                break
            if line is not None:
                new.append(line)
        self.lines += new
        status = self._process.poll()
        if status is not None:
            self._thread.join()
            while not self._queue.empty():
                line = self._queue.get_nowait()
                if line is not None:
                    new.append(line)
                    self.lines.append(line)
        return new, status

    def cancel(self):
        if self._process.poll() is None:
            group = os.getpgid(self._process.pid)
            os.killpg(group, signal.SIGTERM)
            try:
                self._process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                os.killpg(group, signal.SIGKILL)
        self._thread.join(timeout=5)

    def wait(self):
        """Runs to the end; the exit status."""
        self._process.wait()
        self._thread.join()
        self.poll()
        return self._process.returncode
