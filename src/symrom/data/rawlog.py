"""One log file's samples as read (``RawLog``), what kind of file a log is (``log_kind``)
and the error a log that cannot be imported raises: shared by the CSV reader
(``importers``) and the bag reader (``bags``)."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from symrom.data.dataset import jump_bounds


class LogError(ValueError):
    """A log file cannot be imported; the message names the file (and line, column)."""


@dataclass
class RawLog:
    """One log file's samples (n rows): arrays in symrom's order and SI units.

    ``jump`` (n,) local jump ids 0..k-1; ``t`` (n,) s since the jump's first
    sample; ``q``, ``dq`` (n, 18); ``ddq`` (n, 18) or None if not logged;
    ``tau`` (n, 12) N m; ``contact`` (n, 4) uint8; ``lines`` (n,) the file's
    line of each sample (None for a bag: rows are counted); ``columns``: the
    header's name of each field's columns (``q``, ``dq``, ``tau``), for messages;
    ``topics``: a bag's topic of each role; ``ddq_dropped``: the jumps whose logged
    accelerations no longer hold (their time base or velocities repaired: ``data.repair``),
    differentiated again by the import; ``period``: s, the nominal period a log without a time
    column was read at (its ``t`` is then row x period), None where the log holds its times.
    """

    path: Path
    layout: str
    sha256: str
    jump: np.ndarray
    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray | None
    tau: np.ndarray
    contact: np.ndarray
    lines: np.ndarray | None = None
    columns: dict[str, tuple[str, ...]] | None = None
    topics: dict[str, str] | None = None
    ddq_dropped: set[int] = field(default_factory=set)
    period: float | None = None

    @property
    def n_jumps(self) -> int:
        return int(self.jump[-1]) + 1

    def bounds(self) -> np.ndarray:
        """(k, 2) ``[start, stop)`` rows of each of the file's jumps."""
        return jump_bounds(self.jump)

    def where(self, row: int) -> str:
        """'FILE, jump J, row R (line L)': a row of the file, for messages (R counts from 0
        within the jump)."""
        j = int(self.jump[row])
        start = int(self.bounds()[j, 0])
        line = f" (line {int(self.lines[row])})" if self.lines is not None else ""
        return f"{self.path}, jump {j}, row {row - start}{line}"


def sha256_file(path: Path) -> str:
    """The SHA-256 (hex) of a file's bytes, or of a folder's files' bytes in path order (a
    ROS 2 bag is a folder)."""
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for p in files:
        with open(p, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


_HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_ROS1_MAGIC = b"#ROSBAG V2.0"
READS = "CSV logs (text), ROS 1 bags (.bag), ROS 2 bag folders (metadata.yaml) and MCAP files (.mcap)"


def log_kind(path: str | os.PathLike) -> str:
    """What a log file is, from its content (not its name): ``csv``, ``ros1``, ``ros2`` (a bag
    folder) or ``mcap``. LogError naming the file for anything else (an HDF5 file, a text file
    named like one, a folder without a ROS 2 bag)."""
    path = Path(path)
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return "ros2"
        raise LogError(f"{path}: is a directory without a metadata.yaml, so not a ROS 2 bag; "
                       f"symrom import reads {READS}")
    try:
        with open(path, "rb") as f:
            head = f.read(16)
    except FileNotFoundError:
        raise LogError(f"{path}: no such file") from None
    except OSError as e:
        raise LogError(f"{path}: cannot read ({e.strerror or e})") from None
    if head.startswith(_HDF5_MAGIC):
        raise LogError(f"{path}: an HDF5 file (a symrom dataset?), not a log; symrom import reads {READS}")
    if head.startswith(_MCAP_MAGIC):
        return "mcap"
    if head.startswith(_ROS1_MAGIC):
        return "ros1"
    suffix = path.suffix.lower()
    if head.startswith(b"SQLite format 3"):
        raise LogError(f"{path}: the database of a ROS 2 bag; give its folder (the one holding "
                       f"metadata.yaml), {path.parent}")
    if suffix in (".h5", ".hdf5", ".hdf", ".bag", ".mcap", ".db3"):
        what = {".bag": "a ROS 1 bag", ".mcap": "an MCAP file", ".db3": "a ROS 2 bag database"}.get(
            suffix, "an HDF5 file")
        raise LogError(f"{path}: named like {what} ({suffix}) but its content is not one (it starts "
                       f"{head[:12]!r}); symrom import reads {READS}; if it is a CSV log, name it .csv")
    return "csv"
