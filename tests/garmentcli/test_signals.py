"""SIGTERM (`kill`, a batch scheduler stopping a job) unwinds a command like Ctrl-C: what it was writing is removed
and its worker processes stop. Each case runs in its own process, stopped while it writes."""

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[2]

PRELUDE = """
import signal, sys, time
from pathlib import Path
from formats.atomic import atomic_dir
from core.distributed import unwind_on_sigterm

def write_slowly(out, name):
    with atomic_dir(Path(out) / name, overwrite=False) as tmp:
        (tmp / "frame_0000.png").write_bytes(b"x")
        print("ready", flush=True)
        time.sleep(120)
"""


def _stopped(script: str, out: Path, readies: int, group_sigint: bool = False):
    """Run `script` (after PRELUDE) with `out`, wait for `readies` lines "ready", send SIGTERM to it alone (or,
    `group_sigint`, SIGINT to its whole process group, as a terminal's Ctrl-C does); returns (exit status, its
    child processes that outlived it)."""
    proc = subprocess.Popen([sys.executable, "-c", PRELUDE + textwrap.dedent(script), str(out)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=group_sigint)
    try:
        seen = b""
        while seen.count(b"ready") < readies:  # workers' lines may interleave ("readyready")
            line = proc.stdout.readline()
            assert line, proc.stderr.read().decode()  # ended before it was ready
            seen += line
        children = psutil.Process(proc.pid).children(recursive=True)
        if group_sigint:
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGTERM)
        status = proc.wait(timeout=60)
        _, alive = psutil.wait_procs(children, timeout=20)
        return status, alive
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sigterm_removes_the_output_being_written_and_exits_143(tmp_path):
    status, _ = _stopped("""
        unwind_on_sigterm()
        write_slowly(sys.argv[1], "render")
    """, tmp_path, 1)
    assert status == 128 + signal.SIGTERM
    assert list(tmp_path.iterdir()) == []  # no hidden '.render.*.partial' left


def test_sigterm_to_the_command_stops_its_local_workers_and_their_outputs(tmp_path):
    """`--workers 2`: the workers (forked) were left simulating and writing their items after the command had
    died; now they unwind with it."""
    status, alive = _stopped("""
        from core.distributed import run_items
        unwind_on_sigterm()
        for _ in run_items(write_slowly, [(sys.argv[1], "a"), (sys.argv[1], "b")], ["a", "b"], workers=2):
            pass
    """, tmp_path, 2)
    assert status == 128 + signal.SIGTERM and alive == []
    assert list(tmp_path.iterdir()) == []


def test_sigterm_while_the_command_holds_a_finished_item_stops_the_other_workers(tmp_path):
    """The command stopped while it writes an item a worker finished (outside `run_items`' loop, which the unwinding
    closes at its yield): the worker still writing its item is stopped and its output removed, not waited for."""
    status, alive = _stopped("""
        from core.distributed import run_items

        def quick_or_slow(out, name):
            return name if name == "a" else write_slowly(out, name)

        unwind_on_sigterm()
        for name, _ in run_items(quick_or_slow, [(sys.argv[1], "a"), (sys.argv[1], "b")], ["a", "b"], workers=2):
            print("ready", flush=True)  # holding item 'a': the SIGTERM comes here
            time.sleep(120)
    """, tmp_path, 2)
    assert status == 128 + signal.SIGTERM and alive == []
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_at_a_terminal_stops_the_workers_and_their_outputs(tmp_path):
    """A terminal's Ctrl-C reaches the command and its `--workers` at once: the workers leave it to the command,
    which stops them (each unwinding its Ctrl-C was cut short by the command's SIGTERM and left its output's hidden
    folder behind, in all of five tries)."""
    status, alive = _stopped("""
        from core.distributed import run_items
        unwind_on_sigterm()
        for _ in run_items(write_slowly, [(sys.argv[1], "a"), (sys.argv[1], "b")], ["a", "b"], workers=2):
            pass
    """, tmp_path, 2, group_sigint=True)
    assert status == -signal.SIGINT and alive == []  # Python's own end of a KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
