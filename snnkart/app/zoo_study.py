"""A zoo study: snnkart's policy kinds and Stable-Baselines3 PPO on one standard gymnasium task,
all with the RL Zoo's PPO settings for it, the same env version, seeds and step budget.

Each run trains (resumable: a run already at its budget is reused), then is scored on the same
seeded episodes: snnkart's kinds by ``snnkart eval`` (the deterministic torch policy), SB3 by its
deterministic ``predict``, and a uniform random policy as the floor of the normalised scores.
The record (``zoo-study.json``) holds every run's evaluation summary and training time, and per
policy the final return over seeds (mean, std, IQM with a 95 % stratified-bootstrap interval, as
rliable computes them) and its score normalised between the random policy and snnkart's ANN.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from snnkart.app.provenance import git_commit
from snnkart.app.reporter import Reporter, Silent
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import EvalRecord, EvalSummary
from snnkart.errors import ConfigError
from snnkart.report.zoo_record import (
    SNNKART_DEFAULTS,
    ZOO_STUDY,
    Sampled,
    ZooDeploy,
    ZooEnergy,
    ZooRun,
    ZooStudyRecord,
    scores,
)
from snnkart.rl import kinds

CONFIG_SCHEMA = "snnkart/zoo-study-config/v1"
SNNKART_KINDS = ("ann", "snn", "sdnn")
POLICIES = (*SNNKART_KINDS, "sb3")
SETTINGS = ("zoo", "snnkart")


@dataclass(frozen=True)
class ZooStudyConfig:
    """A zoo study's TOML (``studies/zoo-*.toml``)."""

    name: str
    data: str  # "reporting" (seeds 101 and up) or "tuning"
    env: str
    policies: tuple[str, ...]
    seeds: tuple[int, ...]
    eval_episodes: int
    eval_seed: int
    steps: int | None = None  # None: the zoo's n_timesteps
    deploy_episodes: int = 5  # one seed of each spiking kind on lava-sim fixed; 0: none
    sets: tuple[str, ...] = ()
    zoo_score: str | None = None  # the zoo's published score, context only
    zoo_score_source: str | None = None
    settings: str = "zoo"  # "zoo": the RL Zoo's tuned PPO settings; "snnkart": snnkart's defaults

    @classmethod
    def read(cls, path: Path) -> ZooStudyConfig:
        try:
            data = tomllib.loads(path.read_text("utf-8"))
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise ConfigError(f"{path}: cannot read the zoo study config: {exc}") from exc
        if data.pop("schema", None) != CONFIG_SCHEMA:
            raise ConfigError(f"{path}: not a zoo study config (schema {CONFIG_SCHEMA!r})")
        try:
            values: dict[str, object] = {
                k: tuple(v) if isinstance(v, list) else v for k, v in data.items()
            }
            cfg = cls(**values)  # type: ignore[arg-type]
        except TypeError as exc:
            raise ConfigError(f"{path}: {exc}") from exc
        unknown = set(cfg.policies) - set(POLICIES)
        if unknown or cfg.data not in ("reporting", "tuning"):
            raise ConfigError(f"{path}: policies are {', '.join(POLICIES)}; data reporting|tuning")
        if cfg.data == "reporting" and min(cfg.seeds) < 101:
            raise ConfigError(f"{path}: reporting data trains on seeds 101 and up")
        if cfg.settings not in SETTINGS:
            raise ConfigError(f"{path}: settings is one of {', '.join(SETTINGS)}")
        if cfg.settings == "snnkart" and cfg.steps is None:
            raise ConfigError(f'{path}: settings = "snnkart" needs steps (the zoo has no budget)')
        if cfg.settings == "snnkart" and "sb3" in cfg.policies:
            raise ConfigError(
                f"{path}: settings = \"snnkart\" trains snnkart's kinds with snnkart's defaults, "
                'which Stable-Baselines3 would not share: drop "sb3", or use settings = "zoo" '
                "(the RL Zoo's settings for both, where the zoo has an entry for the env)"
            )
        return cfg


def _snnkart_sets(cfg: ZooStudyConfig, policy: str, seed: int, steps: int) -> list[str]:
    from snnkart.rl.zoo import as_overrides, to_snnkart, zoo_settings

    if cfg.settings == "snnkart":
        sets = [f"env={json.dumps(cfg.env)}"]
    else:
        zoo = as_overrides(to_snnkart(zoo_settings(cfg.env)))
        sets = [s for s in zoo if "total_steps" not in s]
    hidden = next((s.split("=", 1)[1] for s in sets if s.startswith("ann.hidden=")), None)
    if hidden is not None:  # a LIF actor as wide as the ANN's (kinds without one ignore it)
        sets.append(f"snn.hidden={hidden}")
    return [*sets, f"policy={policy}", f"seed={seed}", f"total_steps={steps}", *cfg.sets]


def _train_snnkart(cfg: ZooStudyConfig, policy: str, seed: int, steps: int, run_dir: Path) -> dict:
    from snnkart.rl.config import load_config
    from snnkart.rl.ppo import train

    timing = run_dir / "zoo-train.json"
    if timing.is_file():
        done = json.loads(timing.read_text())
        if done["global_step"] >= steps:
            return dict(done)
    train_cfg = load_config(None, None, _snnkart_sets(cfg, policy, seed, steps))
    first = _saved_step(run_dir)
    start = time.perf_counter()
    result = train(train_cfg, run_dir, threads=1)
    wall = time.perf_counter() - start
    record = {
        "global_step": int(result["global_step"]),
        "wall_s": wall if first == 0 else None,  # None: part of it ran in an earlier session
        "steps_per_s": (result["global_step"] - first) / wall if wall > 0 else None,
        "interrupted": bool(result["interrupted"]),
    }
    if not result["interrupted"]:
        from snnkart.io import write_json

        write_json(timing, record)
    return record


def _saved_step(run_dir: Path) -> int:
    meta = run_dir / "checkpoint.json"
    return int(json.loads(meta.read_text())["global_step"]) if meta.is_file() else 0


def _evaluate(cfg: ZooStudyConfig, policy: str, run_dir: Path) -> EvalSummary:
    """The run's evaluation (reused when it is newer than the run's checkpoint)."""
    out = run_dir / "zoo-eval.json"
    trained = run_dir / ("model.zip" if policy == "sb3" else "checkpoint.pt")
    if out.is_file() and out.stat().st_mtime >= trained.stat().st_mtime:
        return EvalRecord.read(out).summary
    if policy != "sb3":
        from snnkart.app.evaluate import run_eval

        return run_eval(
            run_dir, cfg.eval_episodes, cfg.eval_seed, None, False, None, out, Silent()
        ).summary
    return _scored(cfg, run_dir, out)


def _scored(cfg: ZooStudyConfig, run_dir: Path, out: Path) -> EvalSummary:
    """SB3's evaluation, written as an eval record of its own."""
    from snnkart.contract.eval_record import EVAL_SCHEMA, TrackFields
    from snnkart.rl.zoo_baseline import SB3Predictor

    results, threshold = _episodes_on_task(cfg, lambda env: SB3Predictor(run_dir, cfg.env))
    summary = EvalSummary.of(results, threshold)
    record = EvalRecord(
        **vars(TrackFields.none()),
        schema=EVAL_SCHEMA,
        run=str(run_dir),
        checkpoint=str(run_dir / "model.zip"),
        global_step=None,
        policy="sb3",
        env=cfg.env,
        first_seed=cfg.eval_seed,
        summary=summary,
        episodes=results,
    )
    record.write(out)
    return summary


def random_return(cfg: ZooStudyConfig) -> float:
    """A uniform random policy's mean return on the study's evaluation episodes."""
    from snnkart.rl.zoo_baseline import RandomPredictor

    results, _ = _episodes_on_task(
        cfg, lambda env: RandomPredictor(env.action_space, cfg.eval_seed)
    )
    return float(np.mean([r.episode_return for r in results]))


def _episodes_on_task(cfg: ZooStudyConfig, predictor_for: Any) -> tuple[list[Any], float | None]:
    """The study's evaluation episodes of ``predictor_for(env)`` on the env gymnasium makes
    (as SB3 trained on it, no snnkart wrappers), and the env's reward threshold."""
    from snnkart.envs.resolve import resolve_env
    from snnkart.eval.episodes import run_episodes

    env = resolve_env(cfg.env).make({})
    try:
        results = run_episodes(env, predictor_for(env), cfg.eval_episodes, cfg.eval_seed)
        return results, env.spec.reward_threshold if env.spec is not None else None
    finally:
        env.close()


def _run(
    cfg: ZooStudyConfig,
    settings: Any,
    policy: str,
    seed: int,
    steps: int,
    out: Path,
    reporter: Reporter,
) -> ZooRun:
    """One policy x seed trained (or reused) and scored."""
    from snnkart.rl.zoo_baseline import train_sb3

    run_dir = out / f"{policy}-s{seed}"
    reporter.message(f"{cfg.env} {policy} seed {seed}: training {steps:,} steps")
    timing: Mapping[str, Any]
    if policy == "sb3":
        timing = train_sb3(settings, seed, steps, run_dir)
    else:
        timing = _train_snnkart(cfg, policy, seed, steps, run_dir)
        if timing["interrupted"]:
            raise KeyboardInterrupt
    summary = _evaluate(cfg, policy, run_dir)
    reporter.message(f"  return {summary.mean_return:.1f} +- {summary.std_return:.1f}")
    return ZooRun(
        policy,
        seed,
        str(run_dir),
        int(timing["global_step"]),
        timing.get("wall_s"),
        timing.get("steps_per_s"),
        summary,
    )


def run_zoo_study(cfg: ZooStudyConfig, out: Path, reporter: Reporter) -> ZooStudyRecord:
    """Train and evaluate every policy x seed of ``cfg`` into ``out`` (one run at a time,
    resumable), then write ``out/zoo-study.json`` and ``out/zoo-study.md``."""
    from snnkart.rl.zoo import to_snnkart, zoo_settings
    from snnkart.rl.zoo_baseline import describe

    settings = zoo_settings(cfg.env) if cfg.settings == "zoo" else None
    if settings is None:
        steps = int(cfg.steps or 0)
    else:
        steps = cfg.steps or int(float(settings.values["n_timesteps"]))  # type: ignore[arg-type]
    runs = [
        _run(cfg, settings, policy, seed, steps, out, reporter)
        for policy in cfg.policies
        for seed in cfg.seeds
    ]
    deployed = [
        _deployed(cfg, policy, cfg.seeds[0], out / f"{policy}-s{cfg.seeds[0]}", reporter)
        for policy in cfg.policies
        if policy != "sb3" and kinds.family(policy).spiking and cfg.deploy_episodes > 0
    ]
    floor = random_return(cfg)
    threshold = runs[0].summary.reward_threshold if runs else None
    record = ZooStudyRecord(
        schema=ZOO_STUDY.tag,
        name=cfg.name,
        data=cfg.data,
        env=cfg.env,
        steps=steps,
        eval_episodes=cfg.eval_episodes,
        eval_seed=cfg.eval_seed,
        zoo=dict(describe(settings)) if settings is not None else dict(SNNKART_DEFAULTS),
        unexpressible=[] if settings is None else list(to_snnkart(settings).unexpressible),
        reward_threshold=threshold,
        random_return=floor,
        runs=runs,
        scores=scores(runs, floor, threshold),
        deployed=deployed,
        commit=git_commit(),
        machine=_machine(),
        zoo_score=cfg.zoo_score,
        zoo_score_source=cfg.zoo_score_source,
    )
    record.write(out / "zoo-study.json")
    from snnkart.io import write_text
    from snnkart.report.zoo_table import zoo_markdown

    write_text(out / "zoo-study.md", zoo_markdown([record]))
    return record


def _machine() -> dict[str, str]:
    import os
    import platform

    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": str(os.cpu_count()),
    }


def _deployed(
    cfg: ZooStudyConfig, policy: str, seed: int, run_dir: Path, reporter: Reporter
) -> ZooDeploy:
    """The run exported and deployed on lava-sim fixed (reused when newer than its checkpoint)."""
    out = run_dir / "zoo-deploy-lava-sim-fixed"
    record_file = out / "deploy.json"
    if not (
        record_file.is_file()
        and record_file.stat().st_mtime >= (run_dir / "checkpoint.pt").stat().st_mtime
    ):
        from snnkart.eval.closed_loop import run_deploy
        from snnkart.eval.request import DeployRequest
        from snnkart.export.nir_export import export_nir
        from snnkart.rl.trained import load_run

        reporter.message(f"{cfg.env} {policy} seed {seed}: deploying on lava-sim fixed")
        nir_file, _ = export_nir(load_run(run_dir), run_dir / "policy.nir")
        run_deploy(
            DeployRequest(
                nir_file, "lava-sim", "fixed", cfg.deploy_episodes, cfg.eval_seed, out=out
            )
        )
    r = DeployRecord.read(record_file)
    p, c = r.parity, r.counts
    sd = c.sigma_delta
    synops = sum(sd.synaptic_events) if sd is not None else sum(c.synops)
    return ZooDeploy(
        policy=policy,
        seed=seed,
        deploy_dir=str(out),
        summary=r.summary,
        env_steps=p.env_steps,
        mismatched_windows=p.same_arithmetic_mismatched_windows,
        mismatched_actions=p.same_arithmetic_mismatched_actions,
        float32_identical_action_fraction=p.float32_identical_action_fraction,
        synops_per_env_step=synops / max(c.env_steps, 1),
        ms_per_env_step=r.timing.ms_per_env_step,
        energy=_energy(r),
    )


def _energy(record: DeployRecord) -> ZooEnergy:
    """The deployment's energy per decision on Loihi 2 against the int8 ANN of its widths."""
    from snnkart.app.report import priced_deployment
    from snnkart.energy import goal

    p, ann = priced_deployment(record)
    c = goal.check(p, 1.0)
    return ZooEnergy(
        chip=p.chip,
        baseline=p.baseline,
        ann=ann.label,
        snn_pj=Sampled(**c["snn_pj"]),
        ann_pj=Sampled(**c["ann_pj"]),
        ratio=Sampled(**c["ratio"]),
        period_s=p.period_s,
    )


def load_zoo_config(path: Path) -> ZooStudyConfig | None:
    """The zoo study config at ``path``, or None when it is another kind of study config."""
    try:
        head = tomllib.loads(path.read_text("utf-8")).get("schema")
    except (OSError, tomllib.TOMLDecodeError):
        return None
    return ZooStudyConfig.read(path) if head == CONFIG_SCHEMA else None


__all__ = ["ZooStudyConfig", "ZooStudyRecord", "load_zoo_config", "run_zoo_study"]
