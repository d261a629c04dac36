"""``snnkart eval``: the deterministic policy on seeded episodes, with frozen normalisation,
on torch (a run directory) or on a spiking backend (a run exported on the fly, or a NIR file)."""

from __future__ import annotations

import contextlib
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from snnkart import faults
from snnkart.app.pipeline import refuse_main_job_folder
from snnkart.app.reporter import Reporter
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import EVAL_SCHEMA, EvalRecord, EvalSummary, TrackFields
from snnkart.envs.constants import RENDER_FPS
from snnkart.envs.tracks import track_label
from snnkart.errors import UsageError

if TYPE_CHECKING:
    from snnkart.eval.request import DeployRequest


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def run_eval(
    run_dir: Path,
    episodes: int,
    seed: int,
    checkpoint: str | Path | None,
    render: bool,
    video: Path | None,
    out: Path | None,
    reporter: Reporter,
    track: str | None = None,
    video_episodes: int = 3,
) -> EvalRecord:
    """Evaluate a run's torch policy; write and return the eval record. ``checkpoint``:
    ``latest`` (None), ``best``, an env step or a file
    (:func:`snnkart.rl.run_dir.checkpoint_path`). With ``video``, the first ``video_episodes``
    episodes are filmed (all are scored)."""
    from snnkart.rl.trained import TorchPredictor, load_run

    refuse_main_job_folder(run_dir, exported=False)
    _check_video(video, video_episodes, render)
    run = load_run(run_dir, checkpoint)
    choice = _track_choice(run, track)
    mode = "human" if render else ("rgb_array" if video is not None else None)
    env = run.config.make_env(render_mode=mode, track=None if choice is None else choice.track)
    _check_render(env, mode, run.config.env)
    predictor: Any = TorchPredictor(run, seed=seed)
    if mode is not None and choice is not None and run.policy.layer_sizes():
        predictor = _ShowingActivity(predictor, env.unwrapped)  # a spiking actor's activity
    filmed = min(episodes, video_episodes) if video is not None else 0
    results = _episodes(env, predictor, range(seed, seed + episodes), video, filmed, reporter)
    threshold = run.meta["env_spec"].get("reward_threshold") if choice is None else None
    summary = EvalSummary.of(results, threshold)
    path = out or run_dir / "eval.json"
    record = EvalRecord(
        schema=EVAL_SCHEMA,
        run=str(run_dir),
        checkpoint=str(run.checkpoint),
        global_step=run.meta.get("global_step"),
        policy=run.config.policy,
        env=run.config.env,
        **vars(TrackFields.none() if choice is None else choice.record()),
        first_seed=seed,
        summary=summary,
        episodes=results,
    )
    record.write(path)
    where = run.config.env if choice is None else f"{run.config.env}/{choice.label}"
    reporter.message(
        f"{run.config.policy.upper()} {where} "
        f"(step {run.meta.get('global_step', 0):,}), {episodes} episodes: {describe(summary)}"
    )
    if choice is not None and choice.override:
        reporter.message(
            f"note: track {choice.label} is not the track the policy was trained on "
            f"({track_label(choice.trained['name'], choice.trained['given'])})"
        )
    reporter.message(f"results written to {path}")
    return record


def _check_video(video: Path | None, video_episodes: int, render: bool) -> None:
    from snnkart.eval.video import check_video_path

    if video is not None:
        check_video_path(video)
        if video_episodes < 1:
            raise UsageError(f"--video-episodes must be >= 1, got {video_episodes}")
        if render:
            raise UsageError("choose either --render (a window) or --video (a file), not both")


def _episodes(
    env: Any, predictor: Any, seeds: range, video: Path | None, filmed: int, reporter: Reporter
) -> list[Any]:
    """Run the seeded episodes, the first ``filmed`` of them to ``video`` (every second step,
    then the final step with its outcome); the env is closed after, also on Ctrl-C, which is
    taken between env steps."""
    from snnkart.eval.episodes import run_episodes
    from snnkart.eval.video import Film, video_writer

    with contextlib.ExitStack() as stack:
        stack.callback(env.close)
        stack.enter_context(faults.caught())
        label = f"evaluating, filming {filmed} to {video.name}" if video else "evaluating"
        steps = "video frames" if video else None
        task = stack.enter_context(reporter.progress(label, len(seeds), steps))
        on_step, on_episode = None, lambda r: task.advance()
        if video is not None:
            fps = env.metadata.get("render_fps") or RENDER_FPS  # every second step is filmed
            writer = stack.enter_context(video_writer(video, fps=fps / 2))
            film = Film(env.unwrapped, writer, len(seeds), seeds.start, filmed, on_frame=task.step)
            on_step = film.on_step

            def on_episode(result: Any) -> None:
                film.on_episode(result)
                task.advance()

        return run_episodes(env, predictor, len(seeds), seeds.start, on_step, on_episode)


class _ShowingActivity:
    """A spiking policy's predictor that puts its per-layer firing rates in the env's side
    panel before the env draws the step."""

    def __init__(self, predictor: Any, env: Any) -> None:
        self.predictor, self.env = predictor, env

    def reset(self) -> None:
        self.predictor.reset()

    def predict(self, obs: Any) -> Any:
        action = self.predictor.predict(obs)
        self.env.activity = self.predictor.activity()
        return action


def _check_render(env: Any, mode: str | None, name: str) -> None:
    """Refuse ``--render``/``--video`` on an env that cannot draw itself that way."""
    modes = env.metadata.get("render_modes", [])
    if mode is not None and mode not in modes:
        env.close()
        flag = "--render" if mode == "human" else "--video"
        raise UsageError(
            f"{flag} needs the env to render {mode!r}; {name!r} renders "
            f"{', '.join(map(repr, modes)) or 'nothing'}: leave {flag} out"
        )


def _track_choice(run: Any, track: str | None) -> Any:
    """The track to evaluate on: ``--track``, else the one the run was trained on; None for
    any gymnasium env (no track; ``--track`` is refused)."""
    from snnkart.envs.tracks import embed_track, load_track
    from snnkart.eval.policy_env import TrackChoice

    if run.track is None:
        if track is not None:
            raise UsageError(
                f"--track is for the kart envs; {run.config.env!r} is a gymnasium env: leave "
                "--track out"
            )
        return None
    trained = embed_track(run.track, run.config.track)
    del trained["toml"]
    if track is not None:
        return TrackChoice(load_track(track), track, "--track", trained)
    return TrackChoice(run.track, run.config.track, "run", trained)


def describe(summary: EvalSummary) -> str:
    """An evaluation's summary in one line: a kart env's laps and crashes, any other env's
    return, NeuroBench's risk and whether it is solved."""
    from snnkart.eval.episodes import describe_returns

    if summary.success_rate is None:
        return describe_returns(summary)
    return (
        f"success {summary.success_rate:.0%}, return {summary.mean_return:.2f} "
        f"+- {summary.std_return:.2f}, lap time {_fmt(summary.mean_lap_time)} s, "
        f"crashes {summary.crashes}, stood still {summary.stood_still}, "
        f"time-outs {summary.timeouts}"
    )


def run_eval_exported(
    target: Path,
    checkpoint: str | Path | None,
    request: DeployRequest,
    reporter: Reporter,
    sigma_delta: bool = False,
) -> DeployRecord:
    """Evaluate on a spiking backend: ``target`` is a NIR file, or a run directory exported to a
    temporary NIR file first (``sigma_delta``: a ReLU ANN run converted to a sigma-delta
    network, as ``snnkart export --nir RUN --sigma-delta``); results go to the request's
    ``out`` or ``eval-<backend>-<precision>/`` beside the target."""
    from snnkart.app.deploy import run_deploy_reported

    refuse_main_job_folder(target, exported=True)
    name = f"eval-{request.backend}-{request.precision}"
    with tempfile.TemporaryDirectory(prefix="snnkart-eval-") as tmp:
        if target.is_dir():
            from snnkart.export.nir_export import export_nir
            from snnkart.rl.trained import load_run

            run = load_run(target, checkpoint)
            if sigma_delta:
                from snnkart.export.sigma_delta_export import export_sigma_delta

                nir_file, _ = export_sigma_delta(run, Path(tmp) / "policy.nir")
            else:
                nir_file, _ = export_nir(run, Path(tmp) / "policy.nir")
            default_out = target / name
        else:
            if sigma_delta:
                raise UsageError("--sigma-delta converts a run directory, not a .nir file")
            nir_file, default_out = target, target.parent / name
        out = request.out or default_out
        return run_deploy_reported(replace(request, nir_file=nir_file, out=out), reporter)
