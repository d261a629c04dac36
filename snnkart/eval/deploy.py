"""``snnkart deploy``: run an exported policy (``.nir`` + manifest) in closed loop on a backend,
checking it step by step against the numpy reference, and write metrics, counts and parity.

Backends: ``lava-sim`` (Lava's CPU-simulated Loihi, ``--precision float|fixed``) and
``nir-ref`` (the numpy reference; ``float32``, or the Lava arithmetics ``float64|fixed``).
Every env step of a Lava run is shadowed by two references on the same observation:

- the same-arithmetic reference (float64 for Lava float, fixed for Lava fixed), which must
  agree bit for bit: any differing window is counted and reported (it should be 0);
- the float32 reference in torch's order (what the trained policy computes): the fraction of
  identical actions and the spike flips per million neuron-steps measure what the backend's
  arithmetic (float64, or the quantisation) changes.

Only the two exported files are read, never the training code.
"""

from __future__ import annotations

import contextlib
import platform
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from snnkart import faults
from snnkart.backends.base import BACKENDS, SpikeCounts, SpikingBackend, WindowResult, open_backend
from snnkart.backends.reference import NIRReference
from snnkart.contract.manifest import Manifest, ManifestError
from snnkart.envs.tracks import Track, track_label, track_sha256
from snnkart.errors import DeployError, DeployWriteError, ParityError
from snnkart.eval.episodes import EpisodeResult, EvalSummary, run_episodes
from snnkart.io import write_json

DEPLOY_SCHEMA = "snnkart/deploy/v1"


def check_writable(out_dir: Path) -> None:
    """Fail before the run, not after it, if ``out_dir`` cannot take files."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out_dir):
            pass
    except OSError as exc:
        raise DeployError(
            f"cannot write results to {out_dir}: {exc.strerror or exc}; choose another --out"
        ) from exc


@dataclass(frozen=True)
class TrackChoice:
    """The track a policy runs on, and whether it is the one it was trained on."""

    track: Track
    given: str  # how the user named it, or how the training run named it if embedded
    source: str  # "--track", "embedded" (in the manifest) or "name" (a v1 manifest's)
    trained: dict[str, str]  # name, given and sha256 of the trained track

    @property
    def override(self) -> bool:
        return track_sha256(self.track) != self.trained.get("sha256")

    @property
    def label(self) -> str:
        label = track_label(self.track.name, self.given)
        return label[:-1] + ", embedded)" if self.source == "embedded" and "(" in label else label

    def record(self) -> dict[str, Any]:
        return {
            "track": self.track.name,
            "track_given": self.given,
            "track_source": self.source,
            "track_sha256": track_sha256(self.track),
            "trained_track": self.trained,
            "track_override": self.override,
        }


def resolve_track(manifest: Manifest, track: str | None) -> TrackChoice:
    """``--track`` if given (any track: evaluating elsewhere is a real use), else the track
    embedded in the manifest, else (v1 manifests) the track the manifest names."""
    from snnkart.envs.tracks import TrackError, embedded_track, load_track

    spec = manifest.env
    if manifest.track:
        trained = {k: manifest.track[k] for k in ("name", "given", "sha256")}
    else:
        trained = {"name": spec.get("track", "small_S"), "sha256": spec.get("track_sha256", "")}
    if track is not None:
        try:
            return TrackChoice(load_track(track), str(track), "--track", trained)
        except TrackError as exc:
            raise DeployError(f"--track: {exc}") from exc
    if manifest.track:
        try:
            chosen = embedded_track(manifest.track, "the manifest")
        except TrackError as exc:
            raise DeployError(str(exc)) from exc
        return TrackChoice(chosen, manifest.track["given"], "embedded", trained)
    name = trained["name"]
    try:
        return TrackChoice(load_track(name), name, "name", trained)
    except TrackError as exc:
        raise DeployError(
            f"the manifest ({manifest.schema}, written before tracks were embedded) names track "
            f"{name!r}, which is neither built in nor a file here; pass --track with its file, "
            "or export the run again"
        ) from exc


def make_policy_env(manifest: Manifest, env: str | None, track: str | Track | None) -> Any:
    """The env the manifest describes (optionally another track or env), checked to fit;
    ``track`` None: the manifest's own (see :func:`resolve_track`)."""
    from snnkart.envs import ENV_IDS, make, resolve_env_name
    from snnkart.envs.base import revision_mismatch
    from snnkart.envs.tracks import TrackError

    spec = manifest.env
    mismatch = revision_mismatch(spec.get("revision"))
    if mismatch:
        raise DeployError(
            f"the policy was exported from a run on {mismatch}; retrain the run and export it again"
        )
    name = env or spec.get("env")
    if name is None:
        raise DeployError("the manifest names no env; pass --env")
    try:
        resolved = resolve_env_name(str(name))
    except ValueError as exc:
        where = "--env" if env else "the manifest's env"
        raise DeployError(f"{where}: {exc}") from exc
    if resolved not in ENV_IDS:
        raise DeployError(f"unknown env {name!r}")
    if track is None or isinstance(track, str):
        track = resolve_track(manifest, track).track
    kwargs: dict[str, Any] = {
        "track": track,
        "action_mode": spec.get("action_mode", manifest.action_mode),
    }
    if spec.get("env_config") and resolved == spec.get("env"):
        kwargs["config"] = spec["env_config"]
    try:
        gym_env = make(resolved, **kwargs)
    except (TrackError, ValueError, TypeError) as exc:
        raise DeployError(f"cannot make env {resolved!r}: {exc}") from exc
    obs_dim = int(np.prod(gym_env.observation_space.shape or (0,)))
    if obs_dim != manifest.obs_dim:
        gym_env.close()
        raise DeployError(
            f"the policy takes {manifest.obs_dim} observation values but env {resolved!r} "
            f"observes {obs_dim}; deploy it on the env it was trained on ({spec.get('env')})"
        )
    if spec.get("action_space") and str(gym_env.action_space) != spec["action_space"]:
        gym_env.close()
        raise DeployError(
            f"the policy acts in {spec['action_space']} but env {resolved!r} expects "
            f"{gym_env.action_space}"
        )
    return gym_env


@dataclass
class Parity:
    """Running agreement of a backend with its references over the same observations."""

    env_steps: int = 0
    exact_reference: str | None = None
    exact_mismatched_windows: int = 0
    exact_mismatched_actions: int = 0
    float32_action_agreement: int = 0
    float32_spike_flips: int = 0
    neuron_steps: int = 0
    float32_count_differences: list[int] = field(default_factory=list)
    first_mismatch: dict[str, int] | None = None
    """Where the backend first differed from its same-arithmetic reference: the env step
    (counted over the whole deploy, from 0), the episode, the step within it, the layer and
    the row of the window."""

    def as_dict(self) -> dict[str, Any]:
        n = max(self.env_steps, 1)
        return {
            "env_steps": self.env_steps,
            "same_arithmetic_reference": self.exact_reference,
            "same_arithmetic_mismatched_windows": self.exact_mismatched_windows,
            "same_arithmetic_mismatched_actions": self.exact_mismatched_actions,
            "float32_identical_action_fraction": self.float32_action_agreement / n,
            "float32_spike_flips": self.float32_spike_flips,
            "float32_spike_flips_per_million_neuron_steps": (
                1e6 * self.float32_spike_flips / max(self.neuron_steps, 1)
            ),
            "first_same_arithmetic_mismatch": self.first_mismatch,
        }


def _same_action(a: Any, b: Any) -> bool:
    return bool(np.array_equal(np.asarray(a), np.asarray(b)))


class CheckedPredictor:
    """Runs ``primary`` and, on the same observation, its references; returns primary's action."""

    def __init__(
        self,
        primary: SpikingBackend,
        exact: NIRReference | None,
        float32: NIRReference | None,
    ) -> None:
        self.primary = primary
        self.exact = exact
        self.float32 = float32
        self.parity = Parity(exact_reference=None if exact is None else exact.arithmetic)
        self.step_seconds = 0.0
        self.episode, self.episode_step = -1, 0  # where the first parity mismatch happened

    def reset(self) -> None:
        self.primary.reset()
        self.episode += 1
        self.episode_step = 0

    def predict(self, obs: np.ndarray) -> Any:
        faults.fault_point("step")
        t0 = time.perf_counter()
        window, out = self.primary.step(obs)
        self.step_seconds += time.perf_counter() - t0
        action = self.primary.codec.decode(out)
        p = self.parity
        p.env_steps += 1
        if self.exact is not None:
            ref_window, ref_out = self.exact.step(obs)
            differs = not np.array_equal(window.raster, ref_window.raster)
            p.exact_mismatched_windows += differs
            p.exact_mismatched_actions += not _same_action(action, self.exact.codec.decode(ref_out))
            if differs and p.first_mismatch is None:
                p.first_mismatch = _where(window.raster, ref_window.raster, self.exact.chain.sizes)
                p.first_mismatch.update(
                    env_step=p.env_steps - 1, episode=self.episode, episode_step=self.episode_step
                )
        self.episode_step += 1
        if self.float32 is not None:
            f_window, f_out = self.float32.step(obs)
            p.float32_action_agreement += _same_action(action, self.float32.codec.decode(f_out))
            p.float32_spike_flips += _flips(window, f_window)
            p.neuron_steps += f_window.logical.size
        return action


def _where(raster: np.ndarray, reference: np.ndarray, sizes: tuple[int, ...]) -> dict[str, int]:
    """The first layer (and window row) in which two rasters differ."""
    if raster.shape != reference.shape:
        return {"layer": -1, "row": -1}
    offsets = np.cumsum((0, *sizes))
    for layer in range(len(sizes)):
        cols = slice(int(offsets[layer]), int(offsets[layer + 1]))
        rows = np.flatnonzero((raster[:, cols] != reference[:, cols]).any(axis=1))
        if rows.size:
            return {"layer": layer, "row": int(rows[0])}
    return {"layer": -1, "row": -1}


def _flips(a: WindowResult, b: WindowResult) -> int:
    return int(np.count_nonzero(a.logical != b.logical))


def _counts_delta(now: SpikeCounts, before: dict[str, Any]) -> dict[str, Any]:
    cur = now.as_dict()
    out: dict[str, Any] = {"env_steps": cur["env_steps"] - before["env_steps"]}
    for key in ("spikes", "synops", "neuron_updates"):
        out[key] = [x - y for x, y in zip(cur[key], before[key], strict=True)]
    out["pipeline_overhead"] = {
        key: [
            x - y
            for x, y in zip(
                cur["pipeline_overhead"][key], before["pipeline_overhead"][key], strict=True
            )
        ]
        for key in cur["pipeline_overhead"]
    }
    return out


def open_backends(
    nir_path: Path, backend: str, precision: str, seed: int
) -> tuple[SpikingBackend, NIRReference | None, NIRReference | None]:
    """The backend, its same-arithmetic reference (None for the reference itself) and the
    float32 reference (None when the backend is the float32 reference)."""
    primary = open_backend(nir_path, backend, precision, seed)
    try:
        exact = None
        if backend != "nir-ref":
            exact = NIRReference(nir_path, primary.arithmetic, seed=seed)
        float32 = None
        if primary.arithmetic != "float32" or backend != "nir-ref":
            float32 = NIRReference(nir_path, "float32", seed=seed)
    except BaseException:
        primary.close()
        raise
    return primary, exact, float32


def run_deploy(
    nir_path: Path,
    backend: str = "lava-sim",
    precision: str = "fixed",
    episodes: int = 10,
    seed: int = 10_000,
    env: str | None = None,
    track: str | None = None,
    out_dir: Path | None = None,
    on_episode: Any = None,
    on_step: Any = None,
) -> dict[str, Any]:
    """Run ``episodes`` seeded episodes; return (and write to ``out_dir/deploy.json``) the record.

    Ctrl-C and SIGTERM (:mod:`snnkart.faults`) are taken between env steps: the backend is
    stopped, nothing is written and :class:`~snnkart.faults.Interrupted` is raised."""
    from snnkart.backends.reference import load_chain

    if episodes < 1:
        raise DeployError(f"--episodes must be >= 1, got {episodes}")
    nir_path = Path(nir_path)
    _, manifest = load_chain(nir_path)  # fails fast on a bad file before starting Lava
    choice = resolve_track(manifest, track)
    gym_env = make_policy_env(manifest, env, choice.track)
    if out_dir is not None:
        check_writable(out_dir)
    with contextlib.ExitStack() as stack:
        stack.callback(gym_env.close)
        stack.enter_context(faults.caught())  # entered after gym_env.close: exits before it
        t0 = time.perf_counter()
        primary, exact, float32 = open_backends(nir_path, backend, precision, seed)
        stack.push(primary.__exit__)  # stops Lava on success, error and Ctrl-C
        startup = time.perf_counter() - t0
        checked = CheckedPredictor(primary, exact, float32)
        per_episode: list[dict[str, Any]] = []
        before = primary.counts.as_dict()

        def episode_done(result: EpisodeResult) -> None:
            nonlocal before
            per_episode.append({**asdict(result), "counts": _counts_delta(primary.counts, before)})
            before = primary.counts.as_dict()
            if on_episode is not None:
                on_episode(result)

        wall = time.perf_counter()
        results = run_episodes(
            gym_env, checked, episodes, seed, on_step=on_step, on_episode=episode_done
        )
        wall = time.perf_counter() - wall
    summary = EvalSummary.of(results)
    steps = checked.parity.env_steps
    record = {
        "schema": DEPLOY_SCHEMA,
        "backend": backend,
        "precision": precision if backend == "lava-sim" else primary.arithmetic,
        "nir_file": str(nir_path),
        "manifest": {
            "num_steps": manifest.num_steps,
            "encoding": manifest.encoding,
            "layers": [asdict(layer) for layer in manifest.layers],
            "action_mode": manifest.action_mode,
            "training": manifest.training,
        },
        "env": {
            "env": gym_env.unwrapped.env_name,
            **choice.record(),
            "track_label": choice.label,
            "action_mode": gym_env.unwrapped.action_mode,
        },
        "first_seed": seed,
        "summary": asdict(summary),
        "counts": primary.counts.as_dict(),
        "counts_note": (
            "spikes, synops (spikes x fan-out) and neuron_updates of the policy's T logical "
            "SNN steps per env step; pipeline_overhead: the Lava pipeline's fill and drain steps "
            "(L Dense delays per window), not part of the policy's computation"
        ),
        "parity": checked.parity.as_dict(),
        "timing": {
            "startup_s": startup,
            "wall_s": wall,
            "ms_per_env_step": 1000 * checked.step_seconds / max(steps, 1),
        },
        "quantization": None if primary.fixed is None else primary.fixed.describe(),
        "machine": {"python": platform.python_version(), "machine": platform.machine()},
        "versions": manifest.versions,
        "episodes": per_episode,
    }
    if out_dir is not None:
        path = out_dir / "deploy.json"
        try:
            faults.fault_point("deploy-write")
            write_json(path, record)
        except OSError as exc:
            raise DeployWriteError(
                f"the run finished but {path} could not be written: {exc.strerror or exc}; "
                "its summary is printed above; free space or choose another --out and run again",
                record,
            ) from exc
    check_parity(record)
    return record


def check_parity(record: dict[str, Any]) -> None:
    """Raise :class:`ParityError` if any env step differed from the same-arithmetic reference:
    "every env step checked" is a guard, not only a measurement."""
    p = record["parity"]
    bad = p.get("same_arithmetic_mismatched_windows", 0)
    if not bad:
        return
    first = p.get("first_same_arithmetic_mismatch") or {}
    layer = first.get("layer", -1)
    raise ParityError(
        f"parity failure: {record['backend']} ({record['precision']}) differs from the numpy "
        f"reference ({p['same_arithmetic_reference']}) in {bad} of {p['env_steps']} env steps; "
        f"the first is env step {first.get('env_step')} (episode {first.get('episode')}, step "
        f"{first.get('episode_step')}), "
        + (f"layer {layer}, window row {first.get('row')}" if layer >= 0 else "window shape")
        + "; this is a bug in the backend or the reference (please report it with the NIR file)",
        record,
    )


def summary_lines(record: dict[str, Any]) -> list[str]:
    """What ``snnkart deploy`` prints."""
    s, p, c, t = record["summary"], record["parity"], record["counts"], record["timing"]
    n = max(c["env_steps"], 1)
    e = record["env"]
    lines = [
        f"{record['backend']} ({record['precision']}) on {e['env']}/"
        f"{e.get('track_label', e['track'])}, {s['episodes']} episodes: success "
        f"{s['success_rate']:.0%}, return {s['mean_return']:.2f}, crashes {s['crashes']}, "
        f"time-outs {s['timeouts']}",
    ]
    if e.get("track_override"):
        trained = e["trained_track"]
        lines.append(
            f"note: track {e['track_label']} is not the track the policy was trained on "
            f"({track_label(trained['name'], trained.get('given'))})"
        )
    if p["same_arithmetic_reference"] is not None:
        lines.append(
            f"parity vs numpy reference ({p['same_arithmetic_reference']}, same arithmetic): "
            f"{p['same_arithmetic_mismatched_windows']} of {p['env_steps']} env steps differ "
            f"(spike rasters), {p['same_arithmetic_mismatched_actions']} actions differ"
        )
    if p["env_steps"] and "float32_identical_action_fraction" in p:
        lines.append(
            f"agreement with the float32 policy (torch order): "
            f"{p['float32_identical_action_fraction']:.2%} identical actions, "
            f"{p['float32_spike_flips_per_million_neuron_steps']:.0f} spike flips per million "
            "neuron-steps"
        )
    lines.append(
        "per env step (policy): spikes "
        + ", ".join(f"L{i}: {x / n:.1f}" for i, x in enumerate(c["spikes"]))
        + "; synops "
        + ", ".join(f"L{i}: {x / n:.0f}" for i, x in enumerate(c["synops"]))
    )
    o = c["pipeline_overhead"]
    lines.append(
        "pipeline overhead per env step (fill/drain, not the policy): spikes "
        + ", ".join(f"L{i}: {x / n:.2f}" for i, x in enumerate(o["spikes"]))
        + "; neuron updates "
        + ", ".join(f"L{i}: {x / n:.0f}" for i, x in enumerate(o["neuron_updates"]))
    )
    lines.append(f"{t['ms_per_env_step']:.1f} ms per env step, start-up {t['startup_s']:.1f} s")
    return lines


__all__ = [
    "BACKENDS",
    "DeployError",
    "DeployWriteError",
    "ManifestError",
    "ParityError",
    "run_deploy",
    "summary_lines",
]
