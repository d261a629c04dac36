"""The deployment manifest: everything a backend needs that a NIR graph does not carry.

A NIR file describes the spiking actor's per-step graph (Affine -> LIF -> Affine -> LIF ->
Affine). The manifest beside it records how to drive it: the discretisation convention, T SNN
steps per env step with membranes reset at each env step, the input encoding and the host-side
observation normalisation, the readout (mean over the T steps of the last Affine's output) and
the action decoding, and the env the policy was trained on. A backend needs only these two
files, never the training code. This module imports neither torch nor Lava.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from snnkart.contract.sigma_delta import SigmaDeltaBlock
from snnkart.errors import ManifestError
from snnkart.io import atomic_path

MANIFEST_SCHEMA = "snnkart/manifest/v4"
SCHEMA_FILE = Path(__file__).with_name("manifest.schema.json")
"""The JSON Schema of a v2 manifest (for other tools; this module validates in ``__post_init__``)."""
"""v4 adds ``obs_node``: the graph takes the raw observation, its first node (an Affine of
weight ``diag(1 / obs_std)`` and bias ``-obs_mean / obs_std``) normalises it; v3 and older
graphs take the normalised observation. v3 adds ``state_persists`` (membranes carry across
env steps: a stateful LIF policy) and ``sigma_delta`` (a sigma-delta policy, :mod:`snnkart.contract.sigma_delta`); v2 manifests load
with neither. v2 embeds the track (``track``: name, the path as given, hash, TOML); v1 manifests
still load, and their env is rebuilt from the track's name in ``env``, which must then exist."""
READABLE_SCHEMAS = (
    "snnkart/manifest/v1",
    "snnkart/manifest/v2",
    "snnkart/manifest/v3",
    MANIFEST_SCHEMA,
)
ENCODINGS = ("current", "rate", "population", "delta")
ACTION_MODES = ("discrete", "continuous")


@dataclass(frozen=True)
class LayerSpec:
    """One LIF population: its NIR node name, size and the shared decay and threshold (and a
    CubaLIF's shared current decay ``alpha``; None for a LIF)."""

    node: str
    size: int
    beta: float
    threshold: float
    alpha: float | None = None


@dataclass(frozen=True)
class Manifest:
    schema: str
    nir_file: str
    nir_dt: float  # the dt of the NIR time constants: tau = dt / (1 - beta), r = tau / dt
    num_steps: int  # T SNN steps per env step; membranes reset to 0 before each (but see
    # state_persists: then each env step is T + L Lava steps from the last one's state)
    layers: tuple[LayerSpec, ...]
    encoding: str  # "current" | "rate" | "population"
    obs_mean: tuple[float, ...]
    obs_std: tuple[float, ...]  # sqrt(var + eps), divided by
    obs_clip: float
    obs_low: tuple[float, ...]
    obs_high: tuple[float, ...]
    readout_node: str
    action_mode: str  # "discrete": argmax; "continuous": clip to [-1, 1]
    env: dict[str, object]  # the env spec it was trained in (snnkart.envs.spec.env_spec)
    versions: dict[str, str]
    training: dict[str, object] = field(default_factory=dict)  # run, step, ... (export)
    encoding_rng: str | None = None  # rate encoding: how every backend draws the input spikes
    track: dict[str, str] | None = None  # the trained track (v2; None in v1 manifests)
    population: int | None = None  # population encoding: receptive fields per observation
    discretisation: str = "euler"  # of the time constants at nir_dt: euler or exact (exp)
    state_persists: bool = False  # v3: no reset per env step, the state carries on, zeroed
    # at an episode's start (docs/stateful.md)
    sigma_delta: SigmaDeltaBlock | None = None  # v3: a sigma-delta policy (layers is empty)
    obs_node: str | None = None  # v4: the graph's normalisation node (the graph takes the raw
    # observation); the host applies it as the normalisation above, clip included

    def __post_init__(self) -> None:
        """A manifest is valid from construction on, however it was made."""
        if self.schema not in READABLE_SCHEMAS:
            raise ManifestError(
                f"schema {self.schema!r} is not one of {', '.join(map(repr, READABLE_SCHEMAS))}"
            )
        gym = self.env.get("kind") == "gymnasium"  # any gymnasium env: no track
        if self.schema != READABLE_SCHEMAS[0] and not gym and not isinstance(self.track, dict):
            raise ManifestError(f"a {MANIFEST_SCHEMA} manifest embeds its track")
        if self.encoding not in ENCODINGS:
            raise ManifestError(f"unknown encoding {self.encoding!r}; choose one of {ENCODINGS}")
        if (self.encoding == "population") != (self.population is not None) or (
            self.population is not None and self.population < 2
        ):
            raise ManifestError(
                "population (receptive fields per observation, >= 2) is given exactly when the "
                f"encoding is 'population' (encoding {self.encoding!r}, population "
                f"{self.population!r})"
            )
        if self.action_mode not in ACTION_MODES:
            raise ManifestError(
                f"unknown action_mode {self.action_mode!r}; choose one of {ACTION_MODES}"
            )
        if self.discretisation not in ("euler", "exact"):
            raise ManifestError(
                f"unknown discretisation {self.discretisation!r}; choose 'euler' or 'exact'"
            )
        if self.num_steps < 1 or not (self.layers or self.sigma_delta):
            raise ManifestError("a manifest needs num_steps >= 1 and at least one layer")
        if (self.sigma_delta is not None) != (self.encoding == "delta") or (
            self.sigma_delta is not None and (self.layers or self.num_steps != 1)
        ):
            raise ManifestError(
                "a sigma-delta manifest has encoding 'delta', num_steps 1, no LIF layers and a "
                "sigma_delta block; a LIF manifest has none of them"
            )
        dims = {len(getattr(self, k)) for k in ("obs_mean", "obs_std", "obs_low", "obs_high")}
        if len(dims) != 1:
            raise ManifestError("obs_mean, obs_std, obs_low and obs_high differ in length")
        if any(s <= 0 for s in self.obs_std):
            raise ManifestError("obs_std must be positive (it divides the observation)")

    @property
    def obs_dim(self) -> int:
        return len(self.obs_mean)

    @property
    def input_size(self) -> int:
        """The graph's input size: one per observation value, or ``population`` per value."""
        return self.obs_dim * (self.population or 1)

    def to_json(self) -> str:
        data = asdict(self)
        for layer in data["layers"]:  # a LIF layer's manifest entry is what it always was
            if layer["alpha"] is None:
                del layer["alpha"]
        if data["discretisation"] == "euler":  # the default, as every manifest before it
            del data["discretisation"]
        if self.sigma_delta is not None:
            data["sigma_delta"] = self.sigma_delta.as_dict()
        return json.dumps(data, indent=2) + "\n"

    @classmethod
    def from_json(cls, text: str, source: str = "manifest") -> Manifest:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ManifestError(f"{source}: not valid JSON ({exc})") from exc
        if not isinstance(data, dict) or data.get("schema") not in READABLE_SCHEMAS:
            found = data.get("schema") if isinstance(data, dict) else type(data).__name__
            raise ManifestError(
                f"{source}: schema {found!r} is not one of {', '.join(map(repr, READABLE_SCHEMAS))}"
            )
        try:
            data["layers"] = tuple(LayerSpec(**layer) for layer in data["layers"])
            for key in ("obs_mean", "obs_std", "obs_low", "obs_high"):
                data[key] = tuple(float(x) for x in data[key])
            if data.get("sigma_delta") is not None:
                data["sigma_delta"] = SigmaDeltaBlock.from_dict(data["sigma_delta"])
            return cls(**data)
        except (KeyError, TypeError) as exc:
            raise ManifestError(f"{source}: malformed manifest ({exc})") from exc
        except ManifestError as exc:
            raise ManifestError(f"{source}: {exc}") from None

    def write(self, path: Path) -> None:
        with atomic_path(path) as tmp:
            tmp.write_text(self.to_json())

    @classmethod
    def read(cls, path: Path) -> Manifest:
        path = Path(path)
        if not path.is_file():
            raise ManifestError(
                f"no manifest at {path}; it is written next to the .nir file by "
                "`snnkart export --nir`"
            )
        return cls.from_json(path.read_text(), str(path))


def manifest_path(nir_path: Path) -> Path:
    """The manifest that belongs to a NIR file: ``policy.nir`` -> ``policy.manifest.json``."""
    nir_path = Path(nir_path)
    return nir_path.with_name(nir_path.stem + ".manifest.json")
