"""``deploy.json``: what ``snnkart deploy`` (and ``snnkart eval --backend``) measured of an
exported policy on a backend: the episodes, the operation counts, the parity with the numpy
reference, the timing and the quantisation. The energy report and the study read it.
Versioned by the rule in :mod:`snnkart.contract.records`."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from snnkart.contract.eval_record import EpisodeResult, EvalSummary
from snnkart.contract.manifest import LayerSpec, Manifest
from snnkart.contract.records import OMIT_NONE, Record, RecordKind

DEPLOY = RecordKind("deploy", 4, rerun="snnkart deploy")
"""v2 adds ``counts.sigma_delta`` (a sigma-delta policy's counts); v1 files load. v3 (issue
45): any gymnasium env (no track keys), the summary's ``risk``, ``reward_threshold`` and
``solved`` (:class:`~snnkart.contract.eval_record.EvalSummary`); v2 files load. v4: the env's
control rate ``env.control_hz`` (a kart env's 60 Hz, a gymnasium env's ``render_fps``); v3 files
load without it."""
DEPLOY_SCHEMA = DEPLOY.tag
SCHEMA_FILE = Path(__file__).with_name("deploy.schema.json")
COUNTS_NOTE = (
    "spikes, synops (spikes x fan-out) and neuron_updates of the policy's T logical "
    "SNN steps per env step; pipeline_overhead: the Lava pipeline's fill and drain "
    "steps (L Dense delays per window), not part of the policy's computation"
)
SIGMA_DELTA_COUNTS_NOTE = (
    "sigma-delta policy: per sending layer (input Delta = host encoder, each SigmaDelta, "
    "readout Sigma) spikes = messages, synops = synaptic_events, neuron_updates = "
    "updates_clocked over all rows_per_env_step Lava steps (the held schedule); counts.sigma_delta "
    "names every count (snnkart.backends.sigma_delta_counts); no pipeline overhead is split off"
)


@dataclass(frozen=True)
class ManifestSummary:
    """What the energy report needs of the manifest: T, the encoding, the layers, the actions."""

    num_steps: int
    encoding: str = "current"
    population: int | None = None
    layers: tuple[LayerSpec, ...] = ()
    action_mode: str = "discrete"
    training: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, manifest: Manifest) -> ManifestSummary:
        """The manifest's fields of these names."""
        return cls(**{f.name: getattr(manifest, f.name) for f in dataclasses.fields(cls)})


@dataclass(frozen=True)
class NetworkShape:
    """The deployed chain's shape: inputs, spiking layer sizes, outputs, whether it has a
    readout and an input scale."""

    n_in: int
    sizes: tuple[int, ...]
    n_out: int
    readout: bool = True
    input_scale: bool = False


@dataclass(frozen=True)
class EnvRecord:
    """The env and track a deployment ran on, and the track the policy was trained on (records
    of early v1 deployments name only ``env`` and ``track``)."""

    env: str
    track: str | None = field(default=None, metadata=OMIT_NONE)  # None: a gymnasium env
    track_given: str | None = field(default=None, metadata=OMIT_NONE)
    track_source: str | None = field(default=None, metadata=OMIT_NONE)
    track_sha256: str | None = field(default=None, metadata=OMIT_NONE)
    trained_track: dict[str, str] | None = field(default=None, metadata=OMIT_NONE)
    track_override: bool | None = field(default=None, metadata=OMIT_NONE)
    track_label: str | None = field(default=None, metadata=OMIT_NONE)
    action_mode: str | None = field(default=None, metadata=OMIT_NONE)
    control_hz: float | None = field(default=None, metadata=OMIT_NONE)  # v4: decisions per s


@dataclass(frozen=True)
class OverheadCounts:
    """The Lava pipeline's fill and drain steps, per spiking layer (not the policy's work)."""

    spikes: list[int]
    synops: list[int]
    neuron_updates: list[int]


@dataclass(frozen=True)
class SigmaDeltaCounts:
    """A sigma-delta policy's counts, per sending layer (``layers``: ``input`` = the host's
    Delta encoder, each SigmaDelta's node, the readout Sigma's node), summed over env steps of
    ``rows_per_env_step`` Lava steps each; defined in :mod:`snnkart.backends.sigma_delta_counts`."""

    layers: list[str]
    rows_per_env_step: int
    num_message_bits: int
    messages: list[int]
    payload_bits: list[int]
    synaptic_events: list[int]
    updates_clocked: list[int]
    updates_active: list[int]
    host_to_chip_bits: int
    chip_to_host_bits: int

    def minus(self, before: SigmaDeltaCounts) -> SigmaDeltaCounts:
        """The counts since ``before``."""
        lists = ("messages", "payload_bits", "synaptic_events", "updates_clocked", "updates_active")
        diff = {
            k: [a - b for a, b in zip(getattr(self, k), getattr(before, k), strict=True)]
            for k in lists
        }
        return SigmaDeltaCounts(
            layers=self.layers,
            rows_per_env_step=self.rows_per_env_step,
            num_message_bits=self.num_message_bits,
            **diff,
            host_to_chip_bits=self.host_to_chip_bits - before.host_to_chip_bits,
            chip_to_host_bits=self.chip_to_host_bits - before.chip_to_host_bits,
        )


@dataclass(frozen=True)
class Counts:
    """Operation counts per spiking layer over ``env_steps`` env steps (T logical steps each)."""

    env_steps: int
    spikes: list[int]
    synops: list[int]
    neuron_updates: list[int]
    pipeline_overhead: OverheadCounts | None = field(default=None, metadata=OMIT_NONE)
    sigma_delta: SigmaDeltaCounts | None = field(default=None, metadata=OMIT_NONE)

    def minus(self, before: Counts) -> Counts:
        """The counts since ``before`` (one episode's, from the running totals)."""

        def sub(a: list[int], b: list[int]) -> list[int]:
            return [x - y for x, y in zip(a, b, strict=True)]

        now, was = self.pipeline_overhead, before.pipeline_overhead
        overhead = None
        if now is not None and was is not None:
            overhead = OverheadCounts(
                sub(now.spikes, was.spikes),
                sub(now.synops, was.synops),
                sub(now.neuron_updates, was.neuron_updates),
            )
        sd = None
        if self.sigma_delta is not None and before.sigma_delta is not None:
            sd = self.sigma_delta.minus(before.sigma_delta)
        return Counts(
            self.env_steps - before.env_steps,
            sub(self.spikes, before.spikes),
            sub(self.synops, before.synops),
            sub(self.neuron_updates, before.neuron_updates),
            overhead,
            sd,
        )


@dataclass(frozen=True)
class ParityRecord:
    """How the backend agreed with its references over every env step (see
    :mod:`snnkart.eval.parity`)."""

    env_steps: int
    same_arithmetic_reference: str | None
    same_arithmetic_mismatched_windows: int
    same_arithmetic_mismatched_actions: int
    float32_identical_action_fraction: float | None = field(default=None, metadata=OMIT_NONE)
    float32_spike_flips: int | None = field(default=None, metadata=OMIT_NONE)
    float32_spike_flips_per_million_neuron_steps: float | None = field(
        default=None, metadata=OMIT_NONE
    )
    first_same_arithmetic_mismatch: dict[str, int] | None = None
    """Where the backend first differed: env_step, episode, episode_step, layer, row."""


@dataclass(frozen=True)
class Timing:
    startup_s: float
    wall_s: float
    ms_per_env_step: float


@dataclass(frozen=True)
class QuantLayer:
    """One layer's fixed-point parameters, as Lava's fixed point runs them."""

    layer: int
    scale: float
    vth: int
    du: int
    dv: int
    effective_beta: float
    bias_exp: int
    weight_bits: int | None
    max_abs_weight: int | None
    effective_alpha: float | None = field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class Machine:
    python: str
    machine: str


@dataclass
class DeployedEpisode(EpisodeResult):
    """One episode of a deployment, with its own counts."""

    counts: Counts


@dataclass(frozen=True)
class DeployRecord(Record):
    """``deploy.json`` (``snnkart/deploy/v4``)."""

    KIND = DEPLOY

    schema: str
    backend: str
    precision: str
    nir_file: str
    manifest: ManifestSummary
    network: NetworkShape
    env: EnvRecord
    first_seed: int
    summary: EvalSummary
    counts: Counts
    counts_note: str
    parity: ParityRecord
    timing: Timing
    quantization: list[QuantLayer] | None
    machine: Machine
    versions: dict[str, str]
    episodes: list[DeployedEpisode] = field(default_factory=list)

    @property
    def bit_exact(self) -> bool:
        """No env step differed from the same-arithmetic reference, in rasters or actions."""
        p = self.parity
        return p.same_arithmetic_mismatched_windows == 0 == p.same_arithmetic_mismatched_actions


@dataclass(frozen=True, kw_only=True)
class StepCounts:
    """A reference evaluation's counts per env step (one inference) and the network they were
    counted on: what ``snnkart report --sweep`` prices."""

    num_steps: int
    sizes: list[int]
    network: NetworkShape
    precision: str
    encoding: str
    population: int | None = None
    action_mode: str
    env_steps: int
    spikes_per_step: list[float]
    synops_per_step: list[float]
    neuron_updates_per_step: list[float]
    overhead_spikes_per_step: list[float]
    overhead_synops_per_step: list[float]
    overhead_neuron_updates_per_step: list[float]

    @property
    def chip_synops(self) -> float:
        """Synaptic operations per inference on the chip: between spiking layers, not the last
        layer's fan-out to the host's readout."""
        return sum(self.synops_per_step[:-1])

    @classmethod
    def of(cls, deploy: DeployRecord) -> StepCounts:
        """The counts per env step of a deployment (a study's reference evaluation)."""
        manifest, counts = deploy.manifest, deploy.counts
        n = max(counts.env_steps, 1)
        zeros = [0] * len(counts.spikes)
        over = counts.pipeline_overhead or OverheadCounts(zeros, zeros, zeros)
        return cls(
            num_steps=manifest.num_steps,
            sizes=[layer.size for layer in manifest.layers],
            network=deploy.network,
            precision=deploy.precision,
            encoding=manifest.encoding,
            population=manifest.population,
            action_mode=manifest.action_mode,
            env_steps=counts.env_steps,
            spikes_per_step=[s / n for s in counts.spikes],
            synops_per_step=[s / n for s in counts.synops],
            neuron_updates_per_step=[s / n for s in counts.neuron_updates],
            overhead_spikes_per_step=[s / n for s in over.spikes],
            overhead_synops_per_step=[s / n for s in over.synops],
            overhead_neuron_updates_per_step=[s / n for s in over.neuron_updates],
        )
