"""``report.json`` (schema ``snnkart/report/v4``, ``snnkart/report/report.schema.json``) as
typed dicts: a LIF deployment's report (:class:`LifReport`) with its sections, and what the
readers use of a sigma-delta deployment's (:class:`SdReport`).

:mod:`snnkart.app.report` writes the report, :mod:`snnkart.report` and the command line read
it, from memory or from the file; the energy estimate's own sections are
:mod:`snnkart.contract.energy_record`'s. The document writers take the report as any JSON
mapping; :func:`lif_report` and :func:`sd_report` read one as the record it is.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Literal, TypedDict, cast

from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.energy_record import (
    BreakEven,
    Goal,
    Joint,
    ProfileRecord,
    SamplingMethod,
)
from snnkart.contract.records import to_data
from snnkart.contract.sanafe_record import SanafeSection

# -- the deployment and the task ---------------------------------------------------------------


class DeploySection(TypedDict):
    """Where the counts come from (``deploy``): the deployment, its env and track, its parity."""

    file: str
    backend: str
    precision: str
    nir_file: str
    env: str
    track: str | None  # None: a gymnasium env
    track_given: str | None
    track_source: str | None
    episodes: int
    env_steps: int
    first_seed: int
    parity: dict[str, object] | None


def deploy_section(
    record: DeployRecord, deploy_dir: Path, episodes: int, env_steps: int
) -> DeploySection:
    """A report's ``deploy``: the deployment in ``deploy_dir`` (``record``), its env and track,
    its parity, and the episodes and env steps its counts are over."""
    return {
        "file": str(deploy_dir),
        "backend": record.backend,
        "precision": record.precision,
        "nir_file": record.nir_file,
        "env": record.env.env,
        "track": record.env.track,
        "track_given": record.env.track_given,
        "track_source": record.env.track_source,
        "episodes": episodes,
        "env_steps": env_steps,
        "first_seed": record.first_seed,
        "parity": to_data(record.parity),
    }


class Task(TypedDict):
    """A policy's task on the deployment's episodes (``$defs/task``); ``success_rate`` None: a
    gymnasium env without a ``reward_threshold`` (nothing to judge)."""

    success_rate: float | None
    mean_lap_time: float | None
    mean_return: float
    episodes: int
    steps_per_episode: float


class Int8Calibration(TypedDict):
    first_seed: int
    episodes: int
    observations: int
    policy: str


class HostTiming(TypedDict):
    """Wall time of one forward pass, ms: the int8 simulation's and the float actor's."""

    int8: float
    float: float
    what: str


class Int8LayerRecord(TypedDict):
    """One layer of the int8 ANN: its scales and integer widths (``snnkart.rl.int8``)."""

    layer: int
    shape: list[int]
    in_scale: float
    weight_scale: float
    pre_scale: float | None  # None: the output layer (no requantisation)
    multiplier: int
    shift: int
    max_abs_bias: int


class Int8Task(Task):
    """The ANN run quantised to int8, driven on the same episodes (``ann.run.task.int8``)."""

    first_seed: int
    action_agreement: float | None
    agreement_rule: str
    calibration: Int8Calibration
    scheme: str
    layers: list[Int8LayerRecord]
    seconds: dict[str, float]
    host_ms_per_inference: HostTiming


class AnnRunTask(Task):
    """The user's ANN run on the deployment's episodes (``ann.run.task``)."""

    run: str
    global_step: int | None
    first_seed: int
    int8: Int8Task


# -- the networks ------------------------------------------------------------------------------


class NetworkSection(TypedDict):
    n_in: int
    obs_dim: int
    sizes: list[int]
    n_out: int
    num_steps: int
    encoding: str


class Overhead(TypedDict):
    """The Lava pipeline's fill and drain steps, per inference."""

    spikes: list[float]
    synops_chip: list[float]
    neuron_updates: list[float]


class LinkBits(TypedDict):
    host_to_chip: float
    chip_to_host: float


class PerInference(TypedDict):
    """The SNN's counts per inference (``snn.per_inference``)."""

    spikes: list[float]
    synops_chip: list[float]
    neuron_updates: list[float]
    firing_rates: list[float]
    pipeline_overhead: Overhead
    host_ops: list[dict[str, object]]  # what, op, count
    link_bits: LinkBits


class Latency(TypedDict):
    logical_steps: int
    lava_steps_per_action: int
    ms_per_env_step: float
    backend: str


class SnnSection(TypedDict):
    task: Task
    per_inference: PerInference
    neurobench: dict[str, float]
    deployed: dict[str, float]
    footprint: dict[str, int]
    latency: Latency


class AnnSection(TypedDict):
    """One ANN baseline (``ann.same_width``, ``ann.run``); ``task`` None: not run."""

    label: str
    widths: list[int]
    macs: int
    neurobench: dict[str, float]
    footprint: dict[str, int]
    task: AnnRunTask | None


# -- the comparisons ---------------------------------------------------------------------------


class TermRecord(TypedDict):
    """One priced count (``$defs/term``): ``energy_pj = count x price_pj``."""

    part: str
    what: str
    count: float
    profile: str
    op: str
    price_pj: float
    source: str
    energy_pj: float


class Memory(TypedDict):
    """Each side's weight footprint and the memory array it is read from."""

    snn_host_weight_bytes: float
    snn_host_array: str
    ann_weight_bytes: float
    ann_array: str


class AveragePower(TypedDict):
    snn_dynamic: float
    snn_with_static: float
    ann_dynamic: float
    ann_with_static: float


class Static(TypedDict):
    """The verdict with static power over the control period (``comparisons[].static``)."""

    control_period_s: float
    snn_static_pj: float
    ann_static_pj: float
    snn_static_terms: list[TermRecord]
    ann_static_terms: list[TermRecord]
    ratio: float | None
    average_power_w: AveragePower
    not_published: list[dict[str, str]]  # profile, op, why
    note: str


class ComparisonRow(TypedDict):
    """The SNN on one chip against one ANN on one digital target (``comparisons[]``)."""

    snn_profile: str
    host_profile: str
    ann: str  # the key of the ANN in ``ann``
    ann_profile: str
    snn_pj: float
    ann_pj: float
    ratio: float | None
    memory: Memory
    placement: dict[str, object] | None
    static: Static
    not_published: list[dict[str, str]]
    ann_success_rate: float | None
    ann_success: str
    snn_per_episode_pj: float
    ann_per_episode_pj: float | None
    snn_per_return_pj: float | None
    ann_per_return_pj: float | None
    snn_breakdown_pj: dict[str, float]
    ann_breakdown_pj: dict[str, float]
    snn_terms: list[TermRecord]
    ann_terms: list[TermRecord]
    break_even: BreakEven
    uncertainty: Joint


SensitivityRow = TypedDict(
    "SensitivityRow",
    {
        "profile": str,
        "side": str,  # chip, host, digital or host+digital
        "op": str,
        "ratio": float,
        "ratio_low": float,
        "ratio_high": float,
        "ratio_x0.1": float,
        "ratio_x10": float,
    },
)
"""The SNN/ANN ratio with one price moved to either end of its range, and 0.1x and 10x."""


class Sensitivity(TypedDict):
    snn_profile: str
    ann_profile: str
    rows: list[SensitivityRow]


# -- a study's runs, priced (snnkart.app.report_sweep) -----------------------------------------


class _SweepPoint(TypedDict):
    point: str  # the run's variant (its cell without variants)
    seed: int
    num_steps: int
    sizes: list[int]
    success_rate: float
    energy_pj: float


class SweepPoint(_SweepPoint, total=False):
    """One run of the sweep priced; ``kind``: its policy kind's label (none before kinds were
    recorded: a dense LIF run)."""

    kind: str


class Sweep(TypedDict):
    """The report's ``sweep``: a committed study's runs priced on ``profile``, and the ANN's
    energy on each digital profile."""

    file: str
    env: str
    commit: str | None
    profile: str
    host_profile: str
    points: list[SweepPoint]
    ann_64_64_pj: dict[str, float]


# -- the reports -------------------------------------------------------------------------------


class StateNote(TypedDict):
    """A stateful LIF deployment's ``state``: its membranes persist across env steps."""

    state_persists: bool
    rows_per_env_step: str
    note: str


Control = TypedDict(  # "from" is a keyword: the functional form
    "Control",
    {
        "period_s": float,  # one inference per env step, every period_s seconds
        "from": str,  # --control-hz, a kart env's 60 Hz, or a gymnasium env's render_fps
        "pass_mark": str,  # what counts as a successful episode
    },
)
"""The report's control period and the task's pass mark (report v4)."""


class _LifReport(TypedDict):
    schema: str
    deploy: DeploySection
    drives: bool | None  # None: the env has no pass mark
    control: Control
    network: NetworkSection
    snn: SnnSection
    ann: dict[str, AnnSection]  # same_width, and run when an ANN run was given
    host_profile: str
    profiles: dict[str, ProfileRecord]
    comparisons: list[ComparisonRow]
    uncertainty: SamplingMethod
    sensitivity: list[Sensitivity]
    sweep: Sweep | None
    sanafe: SanafeSection


class LifReport(_LifReport, total=False):
    """A LIF deployment's report (no ``kind``); ``state`` for a stateful one; ``figures``
    once written (:func:`snnkart.report.document.write_report` adds the PNGs' names)."""

    state: StateNote
    figures: list[str]


class _SdReport(TypedDict):
    schema: str
    kind: Literal["sigma-delta"]
    deploy: DeploySection
    drives: bool | None
    network: Mapping[str, object]
    task: Task
    sigma_delta: Mapping[str, object]
    ann: Mapping[str, object]
    host_profile: str
    profiles: dict[str, ProfileRecord]
    pricing: list[Mapping[str, object]]
    goal: Goal
    uncertainty: SamplingMethod
    sanafe: Mapping[str, object]
    sweep: Sweep | None


class SdReport(_SdReport, total=False):
    """A sigma-delta deployment's report (``kind: "sigma-delta"``, written by
    :mod:`snnkart.app.report_sigma_delta`): the sections its readers use typed, the rest as written;
    ``figures`` once written."""

    figures: list[str]


def lif_report(report: Mapping[str, object]) -> LifReport:
    """``report`` (:func:`snnkart.app.report.build_report`'s, or ``report.json`` read back) as
    the LIF report it is."""
    return cast(LifReport, report)


def sd_report(report: Mapping[str, object]) -> SdReport:
    """``report`` as the sigma-delta report it is (``kind: "sigma-delta"``)."""
    return cast(SdReport, report)
