"""The results protocol (docs/results.md): every study config declares tuning or reporting data
and may use only that kind's seeds and tracks; no package module reads benchmark results."""

from __future__ import annotations

from pathlib import Path

import pytest

from snnkart.app.study_run import load_study, plan
from snnkart.errors import UsageError

ROOT = Path(__file__).resolve().parents[1]
HEAD = 'schema = "snnkart/study-config/v1"\n'


def _config(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "study.toml"
    path.write_text(HEAD + text)
    return path


def test_a_study_without_a_data_key_is_told_to_add_one(tmp_path: Path) -> None:
    with pytest.raises(UsageError) as info:
        load_study(_config(tmp_path, 'envs = ["grid"]\n'))
    message = str(info.value)
    assert 'study.toml: no data key: add data = "tuning"' in message
    assert 'or data = "reporting"' in message and "\n" not in message


@pytest.mark.parametrize(
    ("text", "refusal"),
    [
        ('data = "tuning"\nseeds = [1, 101]\n', 'data = "tuning", but seed 101 is not tuning'),
        ('data = "tuning"\nseeds = [0]\n', "seed 0 is not tuning data"),
        ('data = "tuning"\ntracks = ["small_S", "benchmarks/tracks/zigzag.toml"]\n',
         "track 'benchmarks/tracks/zigzag.toml' is not tuning data"),
        ('data = "tuning"\ntracks = ["benchmarks/tracks/bends.toml"]\n', "'benchmarks/tracks/bends"),
        ('data = "reporting"\ntracks = ["benchmarks/tracks/zigzag.toml"]\nseeds = [101, 100]\n',
         'data = "reporting", but seed 100 is not reporting data'),
        ('data = "reporting"\nseeds = [101]\ntracks = ["benchmarks/tracks/bends.toml", "benchmarks/tracks/hairpins.toml"]\n',
         "track 'benchmarks/tracks/hairpins.toml' is not reporting data"),
        ('data = "reporting"\nseeds = [101]\ntracks = ["benchmarks/tracks/ring.toml"]\n',
         "track 'benchmarks/tracks/ring.toml' is not reporting data"),
        ('data = "both"\n', "study.toml: data: Input should be 'tuning' or 'reporting'"),
    ],
)  # fmt: skip
def test_a_mix_of_tuning_and_reporting_data_is_refused_naming_it(
    tmp_path: Path, text: str, refusal: str
) -> None:
    with pytest.raises(UsageError) as info:
        load_study(_config(tmp_path, text))
    assert refusal in str(info.value) and "\n" not in str(info.value)


def test_a_setting_that_moves_a_run_onto_other_data_is_refused_both_ways(tmp_path: Path) -> None:
    study = load_study(_config(tmp_path, 'data = "tuning"\nenvs = ["grid"]\nsets = ["seed=150"]\n'))
    with pytest.raises(UsageError, match=r"small_S-grid-ann-s1: .* seed 150 is not tuning data"):
        plan(study)
    study = load_study(_config(tmp_path, 'data = "tuning"\nenvs = ["grid"]\n'
                                         'cells = {"grid-snn" = ["track=big_S", "seed=7"]}\n'))  # fmt: skip
    assert {r.spec.config.track for r in plan(study)} == {"small_S", "big_S"}  # both tuning
    reporting = 'data = "reporting"\nenvs = ["grid"]\nseeds = [101]\n'
    study = load_study(_config(tmp_path, reporting + 'sets = ["seed=5"]\n'))
    with pytest.raises(UsageError, match=r"small_S-grid-ann-s101: .* seed 5 is not reporting data"):
        plan(study)
    study = load_study(_config(tmp_path, reporting + 'variants = {"snn:x" = ["track=big_S"]}\n'))
    assert {r.spec.config.track for r in plan(study)} == {"small_S", "big_S"}  # a task track
    study = load_study(_config(tmp_path, reporting + 'variants = {"snn:x" = '
                                         '["track=benchmarks/tracks/ring.toml"]}\n'))  # fmt: skip
    with pytest.raises(UsageError, match=r"small_S-grid-snn-x-s101: .* 'benchmarks/tracks/ring"):
        plan(study)


def test_each_kind_loads_its_own_data(tmp_path: Path) -> None:
    tuning = load_study(_config(tmp_path, 'data = "tuning"\nseeds = [1, 100]\ntracks = '
                                          '["small_S", "big_S", "benchmarks/tracks/ring.toml", '
                                          '"benchmarks/tracks/hairpins.toml"]\n'))  # fmt: skip
    assert tuning.data == "tuning" and len(plan(tuning)) == 4 * 3 * 2 * 2
    reporting = load_study(_config(tmp_path, 'data = "reporting"\nseeds = [101, 5000]\ntracks = '
                                             '["benchmarks/tracks/zigzag.toml", '
                                             '"benchmarks/tracks/bends.toml"]\n'))  # fmt: skip
    assert reporting.data == "reporting" and len(plan(reporting)) == 2 * 3 * 2 * 2


def test_a_reporting_study_may_train_on_the_originals_tracks_with_reporting_seeds(
    tmp_path: Path,
) -> None:
    """The comparison with kart-simulator is about its two tracks: a reporting study trains on
    them (and on random tracks) with reporting seeds; the ring stays tuning data."""
    study = load_study(_config(tmp_path, 'data = "reporting"\nseeds = [101]\n'
                                         'tracks = ["small_S", "big_S", "random"]\n'))  # fmt: skip
    assert {r.spec.config.track for r in plan(study)} == {"small_S", "big_S", "random"}
    with pytest.raises(UsageError, match="seed 5 is not reporting data"):
        load_study(_config(tmp_path, 'data = "reporting"\nseeds = [5]\n'))


def test_the_committed_studies_declare_their_data() -> None:
    """Every published study is reporting data (issue 36); the screens defaults were chosen
    on stay tuning data. Loading refuses a reporting config that names a tuning seed or track."""
    kinds = {p.stem: load_study(p).data for p in sorted((ROOT / "studies").glob("*.toml"))}
    tuning = {"held-out", "learning", "sparsity"}
    assert {name for name, kind in kinds.items() if kind == "tuning"} == tuning
    assert {name for name, kind in kinds.items() if kind == "reporting"} == set(kinds) - tuning
    assert {"small_S", "big_S", "every-seed", "held-out-reporting", "ablation", "frontier",
            "generalisation", "bc-steer", "bc-gazebo"} <= set(kinds)  # fmt: skip


def test_no_package_module_reads_benchmark_results() -> None:
    """Results are data a study made, never an input of the package: a default is a constant
    in code, and why it is what it is goes in docs/decisions.md."""
    offenders = [
        p.relative_to(ROOT).as_posix()
        for p in sorted((ROOT / "snnkart").rglob("*.py"))
        if "benchmarks/results" in p.read_text() or '"benchmarks"' in p.read_text()
    ]
    assert not offenders, f"these modules name benchmarks/results: {offenders}"
