"""The env a deployed policy runs in: the track (embedded in its manifest, or another one
named with ``--track``) and the env its manifest describes, checked to fit the policy."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from snnkart.contract.eval_record import TrackFields
from snnkart.contract.manifest import Manifest
from snnkart.envs.tracks import Track, track_label, track_sha256
from snnkart.errors import DeployError


@dataclass(frozen=True)
class TrackChoice:
    """The track a policy runs on, and whether it is the one it was trained on."""

    track: Track
    given: str  # how the user named it, or how the training run named it if embedded
    source: str  # "--track", "run" (trained on), "embedded" (in the manifest), "name" (v1)
    trained: dict[str, str]  # name, given and sha256 of the trained track

    @property
    def override(self) -> bool:
        return track_sha256(self.track) != self.trained.get("sha256")

    @property
    def label(self) -> str:
        label = track_label(self.track.name, self.given)
        return label[:-1] + ", embedded)" if self.source == "embedded" and "(" in label else label

    def record(self) -> TrackFields:
        """What the eval and deploy records state of the track."""
        return TrackFields(
            track=self.track.name,
            track_given=self.given,
            track_source=self.source,
            track_sha256=track_sha256(self.track),
            trained_track=self.trained,
            track_override=self.override,
        )


def resolve_track(manifest: Manifest, track: str | None) -> TrackChoice | None:
    """``--track`` if given (any track: evaluating elsewhere is a real use), else the track
    embedded in the manifest, else (v1 manifests) the track the manifest names; None for a
    policy of any gymnasium env (which has no track: ``--track`` is refused)."""
    from snnkart.envs.task_env import is_gym_spec
    from snnkart.envs.tracks import TrackError, embedded_track, load_track

    spec = manifest.env
    if is_gym_spec(spec):
        if track is not None:
            raise DeployError(
                f"--track is for the kart envs; the policy was trained on the gymnasium env "
                f"{spec.get('env')!r}: leave --track out"
            )
        return None
    if manifest.track:
        trained = {k: manifest.track[k] for k in ("name", "given", "sha256")}
    else:
        trained = {
            "name": str(spec.get("track", "small_S")),
            "sha256": str(spec.get("track_sha256", "")),
        }
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
    from snnkart.envs import make, resolve_env_name
    from snnkart.envs.spec import fit_problem, revision_mismatch, trained_env_config
    from snnkart.envs.task_env import is_gym_spec
    from snnkart.envs.tracks import TrackError

    spec = manifest.env
    if is_gym_spec(spec):
        return _gym_policy_env(manifest, env)
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
    if track is None or isinstance(track, str):
        choice = resolve_track(manifest, track)
        assert choice is not None  # a kart env's manifest
        track = choice.track
    kwargs: dict[str, object] = {
        "track": track,
        "action_mode": spec.get("action_mode", manifest.action_mode),
    }
    if spec.get("env_config") and resolved == spec.get("env"):
        # the env it was trained in: terms added since, or on by default now, stay off
        kwargs["config"] = trained_env_config(spec)
    try:
        gym_env = make(resolved, **kwargs)
    except (TrackError, ValueError, TypeError) as exc:
        raise DeployError(f"cannot make env {resolved!r}: {exc}") from exc
    problem = fit_problem({**spec, "obs_dim": manifest.obs_dim}, gym_env)
    if problem:
        gym_env.close()
        raise DeployError(problem)
    return gym_env


def _gym_policy_env(manifest: Manifest, env: str | None) -> Any:
    """The gymnasium env the manifest records, made again from its spec (``env``: another id
    or entry point), refused if its spaces are not the ones the policy was trained on (another
    package version is a warning)."""
    from snnkart.envs.resolve import resolve_env
    from snnkart.envs.task_env import check_trained_on, gym_spec, rebuild
    from snnkart.errors import EnvError

    spec = dict(manifest.env)
    if env is not None:
        spec["name"] = env
    try:
        gym_env = rebuild(spec)
        now = gym_spec(resolve_env(str(spec["name"])), gym_env, _kwargs(spec))
    except EnvError as exc:
        where = "--env" if env else "the manifest's env"
        raise DeployError(f"{where}: {exc}") from exc
    try:
        check_trained_on(manifest.env, now, "run it on that env, or train on this one")
    except EnvError as exc:
        gym_env.close()
        raise DeployError(str(exc)) from exc
    return gym_env


def _kwargs(spec: Mapping[str, object]) -> dict[str, object]:
    kwargs = spec.get("kwargs")
    return kwargs if isinstance(kwargs, dict) else {}
