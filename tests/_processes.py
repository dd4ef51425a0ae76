"""Process helpers for the tests that kill or race ``hammerstein-ctrl`` runs (Linux /proc)."""

import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: Longest wait for a child run to reach the state a test needs.
STARTUP_TIMEOUT = 120.0


def cli(*argv, **kwargs) -> subprocess.Popen:
    """Start ``python -m hammerstein_ctrl.cli *argv`` on this checkout."""
    env = dict(os.environ)
    return subprocess.Popen([sys.executable, "-m", "hammerstein_ctrl.cli", *map(str, argv)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)


def _stat(pid: int):
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text.rsplit(")", 1)[1].split()
    return fields[0], int(fields[1])  # state, parent pid


def alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie awaiting its reaper counts as ended)."""
    st = _stat(pid)
    return st is not None and st[0] not in ("Z", "X")


def children(pid: int) -> list[int]:
    """Live processes whose parent is ``pid``."""
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            st = _stat(int(entry.name))
            if st is not None and st[1] == pid and st[0] not in ("Z", "X"):
                kids.append(int(entry.name))
    return kids


def wait_for(condition, timeout: float = STARTUP_TIMEOUT, step: float = 0.05) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(step)
    return bool(condition())


def lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.is_file() else []
