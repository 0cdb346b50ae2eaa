"""The step trace: per step its absolute tick, axis and direction (numpy arrays)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from galileo_cnc.config.hardware import TICKS_PER_S

TRACE_KEYS = ("tick", "axis", "dir")


@dataclass(frozen=True)
class Trace:
    """Steps in time order; steps of one event share a tick, ordered X, Y, Z.

    `final_position` is the work position (x, y, z steps) after the job and
    `total_ticks` the job's duration (last step or end of a trailing dwell).
    """

    tick: np.ndarray           # int64, absolute timer ticks (0.5 us)
    axis: np.ndarray           # int8, 0 = X, 1 = Y, 2 = Z
    dir: np.ndarray            # int8, +1 / -1
    final_position: tuple[int, int, int]
    total_ticks: int

    def __len__(self) -> int:
        return len(self.tick)

    @property
    def seconds(self) -> float:
        return self.total_ticks / TICKS_PER_S

    def steps_per_axis(self) -> np.ndarray:
        return np.bincount(self.axis, minlength=3)

    def displacement(self) -> np.ndarray:
        """Net steps per axis (x, y, z)."""
        return np.bincount(self.axis, weights=self.dir, minlength=3).astype(np.int64)

    def positions(self, start: tuple[int, int, int] = (0, 0, 0)) -> np.ndarray:
        """Position (len x 3) after every step, from `start`."""
        delta = np.zeros((len(self.tick), 3), dtype=np.int64)
        delta[np.arange(len(self.tick)), self.axis] = self.dir
        return np.asarray(start, dtype=np.int64) + np.cumsum(delta, axis=0)

    def pieces(self, size: int):
        """(tick, axis, dir) views of about `size` steps, each ending at the end of an
        event (the steps of one tick stay together)."""
        lo, total = 0, len(self.tick)
        while lo < total:
            hi = min(lo + size, total)
            while hi < total and self.tick[hi] == self.tick[hi - 1]:
                hi += 1
            yield self.tick[lo:hi], self.axis[lo:hi], self.dir[lo:hi]
            lo = hi

    def same_steps(self, other: "Trace") -> bool:
        return (np.array_equal(self.tick, other.tick) and np.array_equal(self.axis, other.axis)
                and np.array_equal(self.dir, other.dir))

    def save(self, path: str | Path) -> None:
        """`.npz` with tick, axis, dir (+ final_position, total_ticks)."""
        with open(path, "wb") as fh:
            np.savez(fh, tick=self.tick, axis=self.axis, dir=self.dir,
                     final_position=np.asarray(self.final_position, dtype=np.int64),
                     total_ticks=np.asarray(self.total_ticks, dtype=np.int64))

    @classmethod
    def load(cls, path: str | Path) -> "Trace":
        with np.load(path) as data:
            tick = data["tick"].astype(np.int64, copy=False)
            axis = data["axis"].astype(np.int8, copy=False)
            direction = data["dir"].astype(np.int8, copy=False)
            if "final_position" in data:
                final = tuple(int(v) for v in data["final_position"])
            else:
                final = tuple(int(v) for v in
                              np.bincount(axis, weights=direction, minlength=3))
            total = int(data["total_ticks"]) if "total_ticks" in data else (
                int(tick[-1]) if len(tick) else 0)
        return cls(tick, axis, direction, final, total)  # type: ignore[arg-type]
