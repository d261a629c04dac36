"""The deploy tests' runs, trained once per session: four tiny steer SNN policies (current,
continuous, rate and population encoding), each also excited and exported, and the plain
discrete one exported."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

from pathlib import Path

import pytest
from deploy_helpers import RUN_SETS, RUNS, excite
from tiny_runs import train_tiny

from snnkart.export.nir_export import export_nir
from snnkart.rl.trained import LoadedRun, load_run


@pytest.fixture(scope="session")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Tiny trained runs (512 env steps each), trained once for the session."""
    base = tmp_path_factory.mktemp("runs")
    return {
        name: train_tiny(base / name, *spec, extra_sets=RUN_SETS.get(name, ()))
        for name, spec in RUNS.items()
    }


@pytest.fixture(scope="session")
def excited(
    runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[LoadedRun, Path]]:
    """Each run with :func:`excite` applied, and its export (both read-only for the tests)."""
    base = tmp_path_factory.mktemp("excited")
    out = {}
    for name in RUNS:
        run = excite(load_run(runs[name]))
        nir_path, _ = export_nir(run, base / name / "policy.nir")
        out[name] = (run, nir_path)
    return out


@pytest.fixture(scope="session")
def exported(runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The unmodified discrete steer policy's ``policy.nir`` (read-only)."""
    nir_path, _ = export_nir(load_run(runs["steer"]), tmp_path_factory.mktemp("plain") / "p.nir")
    return nir_path
