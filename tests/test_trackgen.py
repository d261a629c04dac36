"""Generated tracks (snnkart.envs.trackgen): the study's benchmark tracks rebuilt byte for byte,
1,000 seeds through the loader's validation with an independent geometry check, gymnasium's
check_env on generated tracks, ``track = "random"`` reproducible per reset seed, and the
``snnkart track generate`` / ``show`` commands."""

from __future__ import annotations

import importlib.util
import io
import warnings
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from snnkart.envs import make
from snnkart.envs.constants import KART_RADIUS_PX
from snnkart.envs.geometry import point_segment_distance
from snnkart.envs.spec import env_spec
from snnkart.envs.trackgen import (
    KINDS,
    WIDTH_RANGE_M,
    WORLD_PX,
    generate_track,
    generated_toml,
    random_marker_toml,
    track_toml,
)
from snnkart.envs.tracks import (
    Track,
    embed_track,
    embedded_track,
    is_random,
    load_track,
    parse_track,
    track_sha256,
)
from snnkart.errors import TrackError

ROOT = Path(__file__).resolve().parents[1]
ENVS = ("grid", "gazebo", "steer")


def _study_designs():
    spec = importlib.util.spec_from_file_location(
        "make_study_tracks", ROOT / "scripts/make_study_tracks.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.DESIGNS


def test_benchmark_tracks_regenerate_byte_identical():
    """scripts/make_study_tracks.py, now built on the package's generator, writes exactly the
    committed benchmarks/tracks/*.toml (zigzag and bends are reporting tracks)."""
    designs = _study_designs()
    assert {d.name for d in designs} == {
        p.stem for p in (ROOT / "benchmarks/tracks").glob("*.toml")
    }
    for design in designs:
        assert (
            track_toml(design).encode()
            == (ROOT / f"benchmarks/tracks/{design.name}.toml").read_bytes()
        ), design.name


def test_random_stand_in_is_generated():
    """snnkart/tracks/random.toml is what random_marker_toml writes (regenerate it if not)."""
    assert (ROOT / "snnkart/tracks/random.toml").read_text() == random_marker_toml()


def _corridor_ok(track: Track) -> None:
    """Independent geometry: inside the world, and the two walls never closer than the
    narrowest allowed corridor (no pinch, no leg laid over another)."""
    xmin, ymin, xmax, ymax = track.bounds
    assert 0 <= xmin and 0 <= ymin and xmax <= WORLD_PX and ymax <= WORLD_PX, track.name
    left, right = (np.asarray(w, dtype=float) for w in track.walls[:2])  # a course: + its cap
    narrowest = WIDTH_RANGE_M[0] * 100 - 2.0  # px, less the coordinates' rounding
    for pts, other in ((left, right), (right, left)):
        segs = np.hstack([other[:-1], other[1:]])
        gaps = [point_segment_distance(tuple(p), segs).min() for p in pts]
        assert min(gaps) >= narrowest, f"{track.name}: walls {min(gaps):.0f} px apart"


def test_thousand_seeds_pass_validation():
    """1,000 seeds (loops and courses, as track="random" draws them) give tracks the loader
    accepts; every 10th also passes the independent geometry check."""
    for seed in range(1000):
        kind = KINDS[seed % 2]
        track = parse_track(generated_toml(seed, kind), source=f"{kind} seed {seed}")
        if seed % 10 < 2:
            _corridor_ok(track)


def test_generation_is_deterministic_per_seed():
    assert generated_toml(17, "course") == generated_toml(17, "course")
    assert generated_toml(17, "course") != generated_toml(18, "course")
    assert generated_toml(17, "loop") != generated_toml(17, "course")
    text = generated_toml(5, "loop", length_m=16.0, width_m=1.1)
    assert "1.10 m corridors" in text and "16.0 m of centreline" in text


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kind": "spiral"}, "unknown track kind 'spiral'"),
        ({"width_m": 0.5}, "corridor width 0.5 m is outside"),
        ({"length_m": 80.0}, "track length 80.0 m is outside 14.0..20.0 m for a loop"),
        ({"seed": -1}, "track seed -1 is negative"),
    ],
)
def test_bad_requests_are_refused(kwargs, message):
    with pytest.raises(TrackError, match=message):
        generated_toml(**{"seed": 1, **kwargs})


def _check(env_name: str, track) -> None:
    env = make(env_name, track=track)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("env_name", ENVS)
def test_check_env_on_generated_and_random_tracks(env_name):
    """check_env on a generated loop, a generated course, and track="random"."""
    _check(env_name, generate_track(0, "loop"))
    _check(env_name, generate_track(1, "course"))
    _check(env_name, "random")


@pytest.mark.slow
@pytest.mark.parametrize("env_name", ENVS)
def test_check_env_fifty_seeds(env_name):
    for seed in range(50):
        _check(env_name, generate_track(seed, KINDS[seed % 2]))


def _trajectory(env, seed: int, steps: int = 40) -> tuple[str, np.ndarray]:
    obs, _ = env.reset(seed=seed)
    rows = [obs]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        obs, *_ = env.step(int(rng.integers(env.action_space.n)))
        rows.append(obs)
    return track_sha256(env.track), np.array(rows)


@pytest.mark.parametrize("env_name", ENVS)
def test_random_track_resets_are_reproducible(env_name):
    """The same reset seed gives the same generated track and trajectory, in any env instance;
    another seed, or the next unseeded reset, another track."""
    a, b = make(env_name, track="random").unwrapped, make(env_name, track="random").unwrapped
    sha_a, traj_a = _trajectory(a, 11)
    sha_b, traj_b = _trajectory(b, 11)
    assert sha_a == sha_b and np.array_equal(traj_a, traj_b)
    a.reset()
    assert track_sha256(a.track) != sha_a
    assert _trajectory(a, 12)[0] != sha_a
    assert _trajectory(a, 11)[0] == sha_a


def test_named_track_stays_put():
    """The default is unchanged: small_S, not random, the same track after any reset."""
    env = make("steer").unwrapped
    assert env.track.name == "small_S" and not env.random_tracks
    before = track_sha256(env.track)
    env.reset(seed=3)
    env.reset()
    assert track_sha256(env.track) == before


def test_random_stand_in_travels_through_specs_and_embedding():
    """Checkpoints and manifests record the stand-in, not the track of the last reset, and the
    embedded stand-in rebuilds an env that draws random tracks again."""
    env = make("gazebo", track="random").unwrapped
    spec0 = env_spec(env)
    env.reset(seed=4)
    assert env.track.name != "random" and env_spec(env) == spec0 and spec0["track"] == "random"
    record = embed_track(env.track_given, "random")
    rebuilt = embedded_track(record, "a checkpoint")
    assert is_random(rebuilt) and is_random(load_track("random"))
    assert not is_random(load_track("small_S")) and not is_random(generate_track(0))
    again = make("gazebo", track=rebuilt).unwrapped
    again.reset(seed=4)
    assert track_sha256(again.track) == track_sha256(env.track)


def test_cli_generate_and_show(tmp_path):
    from PIL import Image
    from typer.testing import CliRunner

    from snnkart.cli.main import app

    out = tmp_path / "c.toml"
    result = CliRunner().invoke(
        app, ["track", "generate", "--seed", "9", "--kind", "course", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert out.read_text() == generated_toml(9, "course")
    assert load_track(out).name == "course-9"
    png = tmp_path / "c.png"
    result = CliRunner().invoke(app, ["track", "show", str(out), "--env", "gazebo", "-o", str(png)])
    assert result.exit_code == 0, result.output
    image = Image.open(io.BytesIO(png.read_bytes()))
    assert image.size[0] > 400 and image.size[1] > 400
    colours = image.convert("RGB").getcolors(1 << 20)
    assert colours is not None and len(colours) > 50  # a drawn figure, not a blank canvas
    result = CliRunner().invoke(
        app, ["track", "show", str(out), "--checkpoint", "40", "-o", str(png)]
    )
    assert result.exit_code == 2 and "no checkpoint 40" in result.output


@pytest.mark.parametrize("seed", range(6))
def test_steer_car_has_a_route_round_every_corner(seed):
    """With the steer car's clearance (its 0.36 m turning radius), a drivable route joins the
    spawn to checkpoint 0 and every checkpoint line to the next: the corners are not too tight."""
    env = make("steer", track=generate_track(seed, KINDS[seed % 2])).unwrapped
    assert env.route_clearance() > KART_RADIUS_PX  # the turning radius, not the body
    track, field = env.track, env.route_field
    starts = [track.spawn_position, *(cp.midpoint for cp in track.checkpoints[:-1])]
    for k, (x, y) in enumerate(starts):
        assert np.isfinite(field.distance(k, x, y)), f"{track.name}: no route to checkpoint {k}"


def test_reporting_tracks_are_committed_and_never_drawn():
    """The generalisation study's 20 reporting tracks: committed files equal to their seeds'
    generation, outside the seeds track="random" draws, and reporting data for the protocol."""
    from snnkart.app.protocol import data_problem
    from snnkart.envs.trackgen import RANDOM_SEEDS, REPORTING_SEEDS

    assert len(set(REPORTING_SEEDS)) == 20 and min(REPORTING_SEEDS) >= RANDOM_SEEDS
    folder = ROOT / "benchmarks/tracks/generated"
    assert len(list(folder.glob("*.toml"))) == 20
    for seed in REPORTING_SEEDS:
        kind = KINDS[seed % 2]
        path = folder / f"{kind}-{seed}.toml"
        assert path.read_text() == generated_toml(seed, kind), path.name
    paths = [str(p) for p in sorted(folder.glob("*.toml"))]
    assert data_problem("reporting", [101], paths) is None
    assert "not tuning data" in data_problem("tuning", [1], paths[:1])


def test_a_course_is_closed_behind_its_start():
    """A generated course has a wall across the corridor behind the spawn (a kart cannot
    leave backwards); the study's own open tracks keep their two walls."""
    course = generate_track(3, "course")
    assert len(course.walls) == 3
    assert len(load_track(ROOT / "benchmarks/tracks/zigzag.toml").walls) == 2


def test_a_policy_trained_on_random_tracks_evaluates_on_both(tmp_path):
    """A tiny run on track="random" carries the stand-in; `eval` runs it on random tracks by
    default (each episode's reset seed its own track) and on a named track with --track."""
    import json

    from tiny_runs import train_tiny
    from typer.testing import CliRunner

    from snnkart.cli.main import app
    from snnkart.rl.trained import load_run

    run = train_tiny(tmp_path / "run", "grid", "ann", total_steps=256, track="random")
    meta = json.loads((run / "checkpoint.json").read_text())
    assert meta["track"]["name"] == "random" and meta["track"]["given"] == "random"
    loaded = load_run(run)
    env = loaded.config.make_env(track=loaded.track).unwrapped  # as eval, replay, report do
    env.reset(seed=5)
    assert env.random_tracks and env.track.name != "random"
    result = CliRunner().invoke(app, ["eval", str(run), "--episodes", "2", "--seed", "1000"])
    assert result.exit_code == 0, result.output
    assert "grid/random" in result.output and "not the track" not in result.output
    result = CliRunner().invoke(app, ["eval", str(run), "--episodes", "1", "--track", "small_S"])
    assert result.exit_code == 0, result.output
    assert "not the track the policy was trained on (random)" in result.output
