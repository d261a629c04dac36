"""``inputs.npz``: what entered a deployment's chip and what each layer sent, per env step, so a
second chip model (SANA-FE, :mod:`snnkart.app.sanafe_report`) can replay the very windows the
backend ran. Written by ``snnkart deploy --out DIR`` beside ``deploy.json``.

Arrays (``E`` env steps, ``T`` logical SNN steps, ``W`` rows per window, ``N = sum(sizes)``):

==================  ===================  ==================================================
``schema``          str                  ``snnkart/inputs/v1``
``current``         ``[E, T, n1]``       the first layer's input current, as the engine got it
                                         (``fixed``: Lava's integer ``a_in``, int32; else
                                         float64, or float32 for the float32 reference);
                                         ``[E, 1, n1]`` when it is held for the T steps
``raster``          ``[E, W, N/8]``      every layer's spikes per engine row (``W = T + depth``:
                                         the Lava pipeline's fill and drain rows included),
                                         bits packed along the neurons (``np.packbits``)
``episode_starts``  ``[episodes]`` int   the env step at which each episode began
``sizes``           ``[layers]`` int     neurons per spiking layer
``meta``            int ``[3]``          ``T``, ``depth``, the first seed
``arithmetic``      str                  ``float32``, ``float64`` or ``fixed``
``backend``         str                  the backend that ran (``lava-sim``, ``nir-ref``)
==================  ===================  ==================================================

Saved compressed (``np.savez_compressed``), read without pickle. A 20-episode run of a 64-64
policy at T = 8 (3,528 env steps, current encoding) takes 0.8 MB: 0.56 MB of
18-bit currents, 0.24 MB of spikes.
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import numpy as np

from snnkart.errors import SnnkartError
from snnkart.io import write_bytes

INPUTS_SCHEMA = "snnkart/inputs/v1"
INPUTS_FILE = "inputs.npz"


class InputsError(SnnkartError, ValueError):
    """An ``inputs.npz`` is missing, unreadable or of another version."""


@dataclass(frozen=True)
class DeployInputs:
    """A deployment's recorded chip inputs and per-layer spikes (module docstring)."""

    current: np.ndarray
    raster: np.ndarray
    episode_starts: np.ndarray
    sizes: tuple[int, ...]
    num_steps: int
    depth: int
    first_seed: int
    arithmetic: str
    backend: str

    def __post_init__(self) -> None:
        e, rows, n = self.raster.shape
        held = self.current.shape[:2] == (e, 1)
        if (
            not (held or self.current.shape[:2] == (e, self.num_steps))
            or rows != self.num_steps + self.depth
        ):
            raise InputsError(
                f"inputs: current {self.current.shape} and raster {self.raster.shape} do not "
                f"fit T = {self.num_steps}, depth {self.depth}; run snnkart deploy again"
            )
        if n != sum(self.sizes):
            raise InputsError(f"inputs: raster has {n} neurons, sizes {self.sizes} sum to another")

    def currents(self, step: int) -> np.ndarray:
        """The first layer's input current of env step ``step``, ``[T, n1]``."""
        c = self.current[step]
        return np.broadcast_to(c, (self.num_steps, c.shape[-1])) if len(c) == 1 else c

    @property
    def env_steps(self) -> int:
        return int(self.raster.shape[0])

    def layer_spikes(self) -> list[int]:
        """Spikes per layer over every row (logical and fill/drain)."""
        offsets = np.cumsum((0, *self.sizes))
        return [int(self.raster[:, :, a:b].sum()) for a, b in pairwise(offsets)]

    def save(self, path: Path) -> None:
        """Write the record to ``path`` atomically (no partial file on a full disk)."""
        buffer = io.BytesIO()  # built in memory: a full disk fails the one write below only
        self._save(buffer)
        write_bytes(path, buffer.getvalue())

    def _save(self, buffer: io.BytesIO) -> None:
        np.savez_compressed(
            buffer,
            schema=np.array(INPUTS_SCHEMA),
            current=_held(self.current),
            raster=np.packbits(self.raster.astype(bool), axis=-1),
            episode_starts=self.episode_starts.astype(np.int64),
            sizes=np.asarray(self.sizes, dtype=np.int64),
            meta=np.asarray([self.num_steps, self.depth, self.first_seed], dtype=np.int64),
            arithmetic=np.array(self.arithmetic),
            backend=np.array(self.backend),
        )

    @classmethod
    def load(cls, path: Path) -> DeployInputs:
        if path.is_dir():
            path = path / INPUTS_FILE
        if not path.is_file():
            raise InputsError(
                f"no {path}: the deployment was run before snnkart recorded its inputs; "
                "run snnkart deploy --out DIR again"
            )
        try:
            with np.load(path, allow_pickle=False) as f:
                schema = str(f["schema"])
                if schema != INPUTS_SCHEMA:
                    raise InputsError(
                        f"{path}: schema {schema!r}, this snnkart reads {INPUTS_SCHEMA}; "
                        "run snnkart deploy --out DIR again"
                    )
                t, depth, seed = (int(x) for x in f["meta"])
                sizes = tuple(int(x) for x in f["sizes"])
                raster = np.unpackbits(f["raster"], axis=-1, count=sum(sizes)).astype(bool)
                return cls(
                    current=f["current"],
                    raster=raster,
                    episode_starts=f["episode_starts"],
                    sizes=sizes,
                    num_steps=t,
                    depth=depth,
                    first_seed=seed,
                    arithmetic=str(f["arithmetic"]),
                    backend=str(f["backend"]),
                )
        except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
            if isinstance(exc, InputsError):
                raise
            raise InputsError(
                f"{path}: not a readable inputs.npz ({exc}); run snnkart deploy again"
            ) from exc


def _held(current: np.ndarray) -> np.ndarray:
    """``current`` ``[E, T, n1]`` as ``[E, 1, n1]`` when every env step holds one current for its
    T steps (current and population encoding), else unchanged."""
    if current.shape[1] > 1 and bool((current == current[:, :1]).all()):
        return current[:, :1]
    return current
