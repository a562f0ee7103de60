"""Running the renderer from Blender: where its programs are, `cargo xtask run`'s
program (`xtask run --bins DIR`) as a child process whose progress lines become
the status bar and whose last error becomes the report, stopped (with every
stage it started) when the user presses Esc, and its image's layers read back."""

import os
import queue
import re
import signal
import subprocess
import threading
import time

from . import exr

# `progress: PROGRAM: LABEL DONE/TOTAL` (pm_stage::Progress with PHOTON_MAP_PROGRESS set).
PROGRESS = re.compile(r"^progress: ([^:]+): (.*) (\d+)/(\d+)\s*$")


# The process group of the last program run (its pid), for scripts and tests.
last_group = None


class Cancelled(Exception):
    """The user stopped the render."""


class Failed(Exception):
    """A stage failed; the message is its one-line error."""


def on_main_thread(fn, stop, schedule):
    """`fn()`'s value, `fn` run on Blender's main thread.

    F12 in Blender's window renders on a job thread, where `bpy.context` has no
    window, view layer or active object, and the glTF exporter fails
    (KhronosGroup/glTF-Blender-IO issue 1943: "'Context' object has no attribute
    'active_object'"); an operator run there would also race the interface. From
    any thread but the main one, `fn` is handed to `schedule` (a queue that a
    timer of Blender's main loop empties: timers run with its first window as
    the context) and the caller waits for it, a tenth of a second at a time,
    asking `stop()` between.
    Headless (`bpy.ops.render.render()` from a script) the render runs on the main
    thread, where `fn` is called at once (timers never run there). `fn`'s
    exception is raised here; `Cancelled` when `stop()` says so before `fn`
    started (once it runs it runs to its end: an export is not interruptible)."""
    if threading.current_thread() is threading.main_thread():
        return fn()
    done, box, lock = threading.Event(), {}, threading.Lock()

    def task():
        with lock:  # either it starts or the waiter cancels it, not both
            if box.get("state") == "cancelled":
                return
            box["state"] = "started"
        try:
            box["value"] = fn()
        except BaseException as e:  # noqa: BLE001 - handed to the waiting thread
            box["error"] = e
        finally:
            done.set()

    schedule(task)
    while not done.wait(0.1):
        with lock:
            if box.get("state") is None and stop():
                box["state"] = "cancelled"
                raise Cancelled()
    if "error" in box:
        raise box["error"]
    return box.get("value")


def binaries(preference, default):
    """The folder of the renderer's programs: $PHOTON_MAP_BIN, else the add-on's
    preference, else where they were built when the add-on was made."""
    folder = os.environ.get("PHOTON_MAP_BIN") or preference or default
    if not folder:
        raise Failed("the renderer's programs are not set: give their folder in the add-on's preferences "
                     "(target/release of the repository, after cargo build --release --workspace)")
    xtask = os.path.join(folder, "xtask" + (".exe" if os.name == "nt" else ""))
    if not os.path.isfile(xtask):
        raise Failed(f"{xtask} is missing: build the renderer (cargo build --release --workspace) "
                     "or set its folder in the add-on's preferences or PHOTON_MAP_BIN")
    return folder, xtask


def _stop(proc):
    """Kill the process and every stage it started (its own process group), and
    wait until none of them is left (at most a second)."""
    if os.name == "nt":
        proc.kill()
        proc.wait()
        return
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()
    for _ in range(100):
        if not running_in_group(proc.pid):
            return
        time.sleep(0.01)


def running_in_group(pgid):
    """True while a process of group `pgid` runs (a killed one waiting to be
    reaped, a zombie, does not)."""
    if not os.path.isdir("/proc"):
        try:
            os.killpg(pgid, 0)
            return True
        except (ProcessLookupError, PermissionError):
            return False
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                with open(f"/proc/{pid}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if fields[0] != "Z" and int(fields[2]) == pgid:
                return True
    return False


def run(cmd, engine, what, stop=None):
    """Run `cmd` to its end, showing its progress lines on `engine` (a
    RenderEngine: update_stats, update_progress, test_break). Raises Cancelled
    when the user stops the render (`engine.test_break()`, or `stop()` when
    given; the processes are killed within a tenth of a second) and Failed with
    the program's one-line error when it fails."""
    stop = stop or engine.test_break
    env = dict(os.environ, PHOTON_MAP_PROGRESS="1")
    global last_group
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                            env=env, text=True, errors="replace", start_new_session=(os.name != "nt"))
    last_group = proc.pid
    lines = queue.Queue()

    def read():
        for line in proc.stdout:
            lines.put(line.rstrip("\n"))
        lines.put(None)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    error, tail, done = "", [], False
    while not done:
        try:
            line = lines.get(timeout=0.05)
        except queue.Empty:
            line = ""
        if line is None:
            done = True
        elif line:
            m = PROGRESS.match(line)
            if m:
                program, label, n, total = m.group(1), m.group(2), int(m.group(3)), int(m.group(4))
                engine.update_stats(what, f"{program}: {label}" + (f" {n}/{total}" if total else ""))
                if total:
                    engine.update_progress(min(n / total, 1.0))
            else:
                tail = (tail + [line])[-20:]
                if line.startswith("error: "):
                    error = line[len("error: "):].strip()
        if stop():
            _stop(proc)
            raise Cancelled()
    proc.wait()
    if proc.returncode != 0:
        raise Failed(error or (tail[-1] if tail else f"{os.path.basename(cmd[0])} exited with {proc.returncode}"))


def layers(xtask, image, folder, engine):
    """The layers of the renderer's `image` (EXR) as {name: height x width x 3
    array, the bottom row first}; `total` is the image itself."""
    run([xtask, "layers", image, "--pfm", folder], engine, "reading the image")
    out = {}
    for f in sorted(os.listdir(folder)):
        if f.endswith(".pfm"):
            out[f[:-4]] = exr.read_pfm(os.path.join(folder, f))
    return out
