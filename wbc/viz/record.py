"""What a replay needs, per tick, in a compact form: :class:`Recording` and its ``.npz`` files.

A paper study writes one file ``DIR/<study>/<study>_replay.npz`` beside its JSON
(:func:`save_recordings`); ``wbc view DIR`` reads every such file below ``DIR``
(:func:`load_recordings`). In the file, run ``NAME`` (e.g. ``"circle_r010/amp_qp"``) is the
arrays ``NAME::t`` [s], ``NAME::q`` (the robot's configuration, ``(N, nq)``), ``NAME::status``
(int8, :data:`STATUS_CODES`) and, when recorded, ``NAME::target`` / ``NAME::ee`` (``(N, 3)``
world positions [m]); the key ``__robot__`` names the robot (a catalogue name,
:func:`wbc.robots.load`). Floats are stored as float32 (0.1 mm on a 100 m trace, plenty for a
picture) and compressed; runs are thinned to at most :data:`MAX_RATE_HZ` frames per second,
a frame keeping the worst status of the ticks it stands for, so a failed tick stays visible.

Needs numpy only (no viser): the studies write records without the ``[viz]`` extra.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wbc.errors import InvalidValueError, ShapeError, UnknownNameError, WbcError

__all__ = ["MAX_RATE_HZ", "STATUS_CODES", "Recording", "load_recordings", "save_recordings"]

#: status code -> meaning: a tick solved, a partial command (a lower level failed, the levels
#: above it were commanded), a failed tick (the fallback command)
STATUS_CODES = {0: "solved", 1: "partial", 2: "failed"}
#: frames per second kept in a file (a replay is watched at up to a few times real time)
MAX_RATE_HZ = 50.0
_ROBOT_KEY = "__robot__"
_SEP = "::"


@dataclass
class Recording:
    """One run as a replay sees it.

    Attributes:
        t: tick start times [s], ``(N,)``.
        q: configurations, ``(N, nq)``.
        status: :data:`STATUS_CODES` per tick, ``(N,)`` int8.
        target: the target position per tick [m] (world), ``(N, 3)``, or ``None``.
        ee: the end effector's position per tick [m] (world), ``(N, 3)``, or ``None`` (the
            viewer then computes it from ``q``).
        robot: the robot's catalogue name, when known.
    """

    t: np.ndarray
    q: np.ndarray
    status: np.ndarray
    target: np.ndarray | None = None
    ee: np.ndarray | None = None
    robot: str | None = None

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        self.q = np.asarray(self.q, dtype=float)
        n = self.t.size
        if n < 1 or self.q.ndim != 2 or self.q.shape[0] != n:
            raise ShapeError(f"a recording needs t (N,) and q (N, nq) with N >= 1, got "
                             f"{self.t.shape} and {self.q.shape}")
        self.status = np.asarray(self.status, dtype=np.int8).reshape(-1)
        if self.status.shape != (n,):
            raise ShapeError(f"status must have shape ({n},), got {self.status.shape}")
        for name in ("target", "ee"):
            value = getattr(self, name)
            if value is not None:
                value = np.asarray(value, dtype=float)
                if value.shape != (n, 3):
                    raise ShapeError(f"{name} must have shape ({n}, 3), got {value.shape}")
                setattr(self, name, value)

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def failures(self) -> int:
        """Ticks (frames) that were not solved: partial or failed."""
        return int(np.count_nonzero(self.status))

    @classmethod
    def from_run(cls, run, target=None, ee=None, robot: str | None = None) -> Recording:
        """The recording of a :class:`wbc.sim.Run` (``run.status`` and ``run.partial`` give
        the status codes); ``target`` / ``ee``: ``(N, 3)`` world positions [m] (a ``(N, 4, 4)``
        pose trace or ``(N, 2)`` floor positions are accepted too)."""
        return cls(run.t, run.q, status_codes(run.status, run.partial), _positions(target),
                   _positions(ee), robot)

    def thinned(self, max_rate_hz: float = MAX_RATE_HZ) -> Recording:
        """At most ``max_rate_hz`` frames per second; a frame keeps the worst status of the
        ticks it stands for."""
        if len(self) < 2:
            return self
        dt = float(np.median(np.diff(self.t)))
        stride = max(1, int(np.floor(1.0 / (max_rate_hz * dt) + 1e-9))) if dt > 0 else 1
        if stride == 1:
            return self
        keep = np.arange(0, len(self), stride)
        worst = np.maximum.reduceat(self.status, keep)
        return Recording(self.t[keep], self.q[keep], worst,
                         None if self.target is None else self.target[keep],
                         None if self.ee is None else self.ee[keep], self.robot)


def status_codes(status, partial=None) -> np.ndarray:
    """:data:`STATUS_CODES` of a run's statuses (``"solved"`` or ``""`` → 0; a failure whose
    command came from the levels above → 1; any other failure → 2)."""
    codes = np.array([0 if s in ("solved", "") else 2 for s in status], dtype=np.int8)
    if partial is not None:
        partial = np.asarray(partial, dtype=bool).reshape(-1)
        codes[(codes == 2) & partial[:codes.size]] = 1
    return codes


def _positions(value) -> np.ndarray | None:
    """``(N, 3)`` positions from ``(N, 3)``, ``(N, 4, 4)`` poses or ``(N, 2)`` floor points."""
    if value is None:
        return None
    value = np.asarray(value, dtype=float)
    if value.ndim == 3 and value.shape[1:] == (4, 4):
        return value[:, :3, 3]
    if value.ndim == 2 and value.shape[1] == 2:
        return np.column_stack([value, np.zeros(len(value))])
    if value.ndim == 2 and value.shape[1] >= 3:
        return value[:, :3]
    raise ShapeError(f"a trace must be (N, 3) positions, (N, 4, 4) poses or (N, 2) floor "
                     f"points, got {value.shape}")


def save_recordings(path: str | os.PathLike[str], recordings: dict[str, Recording],
                    robot: str) -> Path:
    """Write ``recordings`` (``run name -> Recording``, thinned to :data:`MAX_RATE_HZ`) of the
    catalogue robot ``robot`` to the compressed ``.npz`` file ``path``; returns the path."""
    arrays: dict[str, np.ndarray] = {_ROBOT_KEY: np.array(robot)}
    for name, recording in recordings.items():
        if not name or _SEP in name:
            raise InvalidValueError(f"run name {name!r}: must be non-empty, without {_SEP!r}")
        r = recording.thinned()
        arrays[f"{name}{_SEP}t"] = r.t.astype(np.float32)
        arrays[f"{name}{_SEP}q"] = r.q.astype(np.float32)
        arrays[f"{name}{_SEP}status"] = r.status
        for key in ("target", "ee"):
            value = getattr(r, key)
            if value is not None:
                arrays[f"{name}{_SEP}{key}"] = value.astype(np.float32)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]
    return path


def read_recordings(path: str | os.PathLike[str]) -> dict[str, Recording]:
    """The runs of one file written by :func:`save_recordings` (file order)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            robot = str(data[_ROBOT_KEY]) if _ROBOT_KEY in data.files else None
            names = list(dict.fromkeys(k.rpartition(_SEP)[0] for k in data.files
                                       if _SEP in k))
            out = {}
            for name in names:
                def get(key, name=name):
                    k = f"{name}{_SEP}{key}"
                    return data[k].astype(float) if k in data.files else None
                out[name] = Recording(get("t"), get("q"), data[f"{name}{_SEP}status"],
                                      get("target"), get("ee"), robot)
    except (OSError, ValueError, KeyError) as err:
        raise WbcError(f"cannot read the replay file {str(path)!r}: {err}") from None
    return out


def load_recordings(folder: str | os.PathLike[str]) -> dict[str, Recording]:
    """Every run recorded below ``folder`` (a study's folder, or the ``--out`` of
    ``wbc study`` / ``wbc reproduce``), named ``"<study>/<run>"`` (the file's stem without
    ``_replay``), or the runs of ``folder`` itself when it is a ``.npz`` file.

    Raises:
        WbcError: ``folder`` does not exist, or a file cannot be read.
        UnknownNameError: no recording was found below it.
    """
    folder = Path(folder)
    if not folder.exists():
        raise WbcError(f"no such file or folder {str(folder)!r}")
    files = [folder] if folder.is_file() else sorted(folder.rglob("*_replay.npz"))
    out: dict[str, Recording] = {}
    for path in files:
        study = path.stem.removesuffix("_replay")
        for name, recording in read_recordings(path).items():
            out[f"{study}/{name}"] = recording
    if not out:
        raise UnknownNameError(f"no replay records (*_replay.npz) below {str(folder)!r}: run "
                               "`wbc study NAME --out DIR` or `wbc reproduce` first")
    return out
