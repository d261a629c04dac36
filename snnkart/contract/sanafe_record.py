"""The ``sanafe`` entry of a LIF deployment's ``report.json`` (``snnkart/report/report.schema.json``)
as typed dicts: SANA-FE's Loihi model run on the recorded inputs, next to snnkart's Loihi 1
estimate (written by :mod:`snnkart.app.sanafe_report`, read by :mod:`snnkart.report.sanafe_page`).
"""

from __future__ import annotations

from typing import TypedDict


class SanafeRun(TypedDict):
    env_steps: int
    rows_per_env_step: int
    mapping: str
    wall_s: float


class SanafeEstimate(TypedDict):
    """SANA-FE's replay per inference, pJ: energy by component (``total``, ``synapse``,
    ``soma``, ``network``, ...) and by term."""

    energy_pj: dict[str, float]
    terms_pj: dict[str, float]
    unexplained_pj: float
    counts: dict[str, float]
    latency_s: dict[str, float]


class SanafeVersus(TypedDict):
    """One of SANA-FE's terms against snnkart's Loihi 1 estimate."""

    term: str
    why: str
    snnkart_pj: float
    sanafe_pj: float
    ratio_sanafe_to_snnkart: float | None
    over_2x: bool


class SanafeSpikes(TypedDict):
    deploy_json: list[int]
    inputs_npz: list[int]
    replayed_by_sanafe: list[float]
    sanafe_lif_replay: list[float]


class SanafeLifCheck(TypedDict):
    """SANA-FE's own LIF, driven by layer 0's recorded current only."""

    what: str
    env_steps: int
    recorded_spikes: list[float]
    sanafe_spikes: list[float]
    mismatched_logical_neuron_steps: list[int]
    reproduces: bool
    arithmetic: str


SanafeLatency = TypedDict(
    "SanafeLatency",
    {
        "on_chip_s_per_inference": float,
        "max_s": float,
        "from": str,
        "replay_s_per_inference": float,
        "control_period_s": float,
        "fraction_of_control_period": float,
        "steps_per_inference": int,
    },
)


class _Sanafe(TypedDict):
    available: bool


class SanafeSection(_Sanafe, total=False):
    """The report's ``sanafe``: ``available`` false with the ``reason``, or SANA-FE's figures."""

    reason: str
    model: str
    sanafe_version: str | None
    run: SanafeRun
    per_inference: SanafeEstimate
    versus_snnkart_loihi1: list[SanafeVersus]
    spikes_per_layer: SanafeSpikes
    lif_check: SanafeLifCheck
    latency: SanafeLatency
