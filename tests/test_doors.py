"""Every door that opens a trained policy (``snnkart eval``, ``deploy``, ``nir run`` and ``ros
drive``, the Python API, the process pool's worker) reads one table of defaults
(:mod:`snnkart.backends.defaults`): run without ``--precision``, each runs in the table's
default word, its ``--help`` says that default, and the backend registry knows the same words.
Nothing heavy runs: each door is stopped where it hands over to the deployment."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from snnkart.backends.defaults import (
    BACKENDS,
    DEFAULT_PRECISIONS,
    NIR_BACKENDS,
    TABLE,
    default_help,
    precision_word,
)
from snnkart.cli import app
from snnkart.errors import SnnkartError, UsageError

NIR = Path(__file__).parent / "data" / "policies" / "grid-snn-nir-8ddd6dd" / "policy.nir"
RUN = Path(__file__).parent / "data" / "policies" / "grid-snn"


class Stop(SnnkartError):
    """Raised where a door hands over: what it was asked to run is recorded by then."""


def _stop_at(monkeypatch: pytest.MonkeyPatch, target: str, pick: Callable[..., str]) -> list[str]:
    """Replace ``module:function`` by one that records ``pick(*args)`` and raises Stop."""
    seen: list[str] = []
    module, name = target.split(":")

    def stop(*args: Any, **kwargs: Any) -> Any:
        seen.append(pick(*args, **kwargs))
        raise Stop("stopped here")

    monkeypatch.setattr(f"{module}.{name}", stop)
    return seen


def _cli(*args: str) -> None:
    result = CliRunner().invoke(app, list(args))
    assert "stopped here" in result.output, result.output


def _request_precision(where: Any, checkpoint: Any, request: Any, *_: Any, **__: Any) -> str:
    return request.precision


def cli_eval(mp: pytest.MonkeyPatch, backend: str, tmp: Path) -> list[str]:
    seen = _stop_at(mp, "snnkart.app.evaluate:run_eval_exported", _request_precision)
    _cli("eval", str(NIR), "--backend", backend, "--episodes", "1")
    return seen


def cli_deploy(mp: pytest.MonkeyPatch, backend: str, tmp: Path) -> list[str]:
    def word(request: Any, reporter: Any) -> str:  # the default --out names the precision too
        assert request.out.name == f"deploy-{backend}-{request.precision}", request.out
        return request.precision

    seen = _stop_at(mp, "snnkart.app.deploy:run_deploy_reported", word)
    _cli("deploy", str(NIR), "--backend", backend, "--episodes", "1")
    return seen


def cli_nir_run(mp: pytest.MonkeyPatch, backend: str, tmp: Path) -> list[str]:
    seen = _stop_at(mp, "snnkart.app.nir_tools:run_nir_run", lambda *a, **k: a[4])
    _cli("nir", "run", str(NIR), "--input", str(tmp / "x.npy"), "--backend", backend)
    return seen


def cli_ros_drive(mp: pytest.MonkeyPatch, backend: str, tmp: Path) -> list[str]:
    mp.setattr("snnkart.ros.rospy_import.check_master", lambda: None)
    seen = _stop_at(mp, "snnkart.app.ros_bridge:_policy", lambda target: target.precision)
    _cli("ros", "drive", str(NIR), "--backend", backend)
    return seen


def api_load_policy(mp: pytest.MonkeyPatch, backend: str, tmp: Path) -> list[str]:
    import snnkart

    seen = _stop_at(mp, "snnkart.backends.registry:open_backend", lambda p, b, word, s: word)
    with pytest.raises(Stop):
        snnkart.load_policy(NIR, backend=backend)
    return seen


def api_evaluate(mp: pytest.MonkeyPatch, backend: str, tmp: Path) -> list[str]:
    import snnkart

    seen = _stop_at(mp, "snnkart.app.evaluate:run_eval_exported", _request_precision)
    with pytest.raises(Stop):
        snnkart.evaluate(NIR, episodes=1, backend=backend)
    return seen


def worker(mp: pytest.MonkeyPatch, backend: str, tmp: Path) -> list[str]:
    from snnkart.app.worker import EvalJob, run

    seen = _stop_at(mp, "snnkart.app.evaluate:run_eval_exported", _request_precision)
    with pytest.raises(Stop):
        run(EvalJob(str(NIR), 1, 0, str(tmp / "out"), backend))
    return seen


DOORS = [cli_eval, cli_deploy, cli_nir_run, cli_ros_drive, api_load_policy, api_evaluate, worker]


@pytest.mark.parametrize("backend", NIR_BACKENDS)
@pytest.mark.parametrize("door", DOORS, ids=lambda door: door.__name__)
def test_every_door_runs_in_the_tables_default(
    door: Callable[..., list[str]], backend: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    assert door(monkeypatch, backend, tmp_path) == [DEFAULT_PRECISIONS[backend]], door.__name__


def _precision_options() -> list[tuple[str, Any]]:
    """Every command's ``--precision`` option, by command path."""
    found = []

    def walk(command: Any, path: str) -> None:
        for param in getattr(command, "params", []):
            if param.name == "precision":
                found.append((path, param))
        for name, sub in getattr(command, "commands", {}).items():
            walk(sub, f"{path} {name}".strip())

    walk(typer.main.get_command(app), "")
    return found


def test_every_precision_option_defaults_as_the_table_says() -> None:
    """A command leaves --precision out (None: the table's default, shown in --help), or
    defaults to a word that is every NIR backend's default in the table."""
    options = _precision_options()
    assert {"eval", "deploy", "nir run", "ros drive"} <= {path for path, _ in options}
    for path, param in options:
        if param.default is None:
            assert param.show_default == default_help(), path
            for backend in NIR_BACKENDS:
                assert precision_word(backend, None) == DEFAULT_PRECISIONS[backend]
        else:
            for backend in NIR_BACKENDS:
                assert precision_word(backend, param.default) == DEFAULT_PRECISIONS[backend], path


def test_the_help_names_every_word_the_table_takes() -> None:
    for path, param in _precision_options():
        for backend in NIR_BACKENDS:
            for word in TABLE[backend].precisions:
                assert word in param.help, (path, word)


def test_the_registry_knows_the_tables_words() -> None:
    from snnkart.backends import registry
    from snnkart.eval.request import DeployRequest

    assert set(registry.BACKENDS) == set(NIR_BACKENDS)
    for backend in NIR_BACKENDS:
        for word, arithmetic in TABLE[backend].precisions.items():
            assert DeployRequest(NIR, backend, word).arithmetic == arithmetic
    assert TABLE["torch"].precisions == {} and TABLE["torch"].default is None
    assert set(BACKENDS) == {"torch", *NIR_BACKENDS}


def test_the_workers_written_default_is_the_tables() -> None:
    """EvalJob writes its precision out (a study's request keys hash it): the table's."""
    from snnkart.app.worker import EvalJob

    assert {EvalJob("r", 1, 0, "o").precision} == set(DEFAULT_PRECISIONS.values())


# -- the opener's rules, one line each -------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("nothing",), "nothing does not exist; give a run directory, a checkpoint in one or a"),
        (("missing.nir", "nir-ref"), "no NIR file at missing.nir; create one with `snnkart export"),
        ((NIR,), "is an exported policy; torch runs a run directory: choose --backend nir-ref"),
        ((NIR, "loihi"), "unknown backend 'loihi'; choose torch, nir-ref or lava-sim"),
        ((NIR, "lava-sim", "float32"), "lava-sim is float or fixed, not 'float32' (float32 runs"),
        ((NIR, "nir-ref", "half"), "--precision for nir-ref is float32, float64, float or fixed"),
        ((NIR, "nir-ref", None, "best"), "is an exported policy; --checkpoint picks a run"),
        ((RUN / "checkpoint.pt", "torch", None, "best"), "is a checkpoint already; drop"),
        ((Path(__file__).parent,), "is not a run directory (no config.toml)"),
    ],
)
def test_the_opener_refuses_bad_input_in_one_line(args: tuple[Any, ...], message: str) -> None:
    from snnkart.app.opener import choose

    with pytest.raises(UsageError) as err:
        choose(*args)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_checkpoint_opens_its_run_at_that_checkpoint_and_torch_ignores_precision() -> None:
    from snnkart.app.opener import choose

    target = choose(RUN / "checkpoint.pt", "torch", "float64")
    assert (target.run_dir, target.checkpoint, target.precision) == (
        RUN,
        RUN / "checkpoint.pt",
        None,
    )
    assert choose(NIR, "lava-sim").nir_file == NIR
    assert choose(RUN, "nir-ref").precision == DEFAULT_PRECISIONS["nir-ref"]
