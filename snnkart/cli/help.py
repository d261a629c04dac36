"""What ``--help`` shows: every command's examples, and prose that wraps at the terminal's width.

:func:`finish_help` walks the command tree once, after every command is registered. Each
command and group gets its examples as the epilog and is built by a class that tidies its text:
a docstring's single line breaks are joined (the terminal wraps the text, not the source), RST
double backquotes are dropped, and a plain flag shows no ``<bool>`` type.
"""

from __future__ import annotations

import re
from typing import Any

import typer
from rich.markup import escape
from typer.core import TyperCommand, TyperGroup, TyperOption

_RUN, _ANN = "runs/steer-snn", "runs/steer-ann"  # as the README names them
EXAMPLES: dict[str, tuple[str, ...]] = {
    "": ("snnkart demo", "snnkart train --env grid --policy snn", "snnkart eval --help"),
    "play": (
        "snnkart play",
        "snnkart play --env grid --track small_S",
        "snnkart play --env steer --track small_S --record expert.npz",
    ),
    "record": ("snnkart record --driver pursuit --env steer --episodes 20 -o steer-pursuit.npz",),
    "demo": ("snnkart demo --out runs/demo", "snnkart demo --steps 60000 --ann-steps 60000"),
    "train": (
        "snnkart train --env grid --policy snn --out runs/grid-snn",
        "snnkart train --resume --out runs/grid-snn",
        "snnkart train --set ppo.learning_rate=1e-3 --set snn.num_steps=4",
        "snnkart train --policy ann --set ann.activation=relu",
        "snnkart train --policy sdnn --set sdnn.message_penalty=0.05",
        "snnkart train --env grid --wandb",
        "snnkart train --pretrain-bc steer-pursuit.npz --bc-epochs 30",
    ),
    "eval": (
        f"snnkart eval {_RUN} --episodes 50",
        f"snnkart eval {_RUN} --backend nir-ref",
        "snnkart eval runs/grid-relu --backend nir-ref --sigma-delta",
    ),
    "replay": (f"snnkart replay {_RUN} --mode all", f"snnkart replay --compare {_ANN} {_RUN}"),
    "export": (
        f"snnkart export {_RUN} --nir",
        "snnkart export runs/steer-sdnn --nir --sigma-delta-target 0.98",
        f"snnkart export {_ANN} --nir --sigma-delta --calibration-episodes 5",
    ),
    "deploy": (
        f"snnkart deploy {_RUN}/policy.nir --episodes 5",
        f"snnkart deploy {_RUN}/policy.nir --backend nir-ref --precision float32",
    ),
    "report": (f"snnkart report {_RUN}/deploy-lava-sim-fixed --ann {_ANN}",),
    "sweep": ("snnkart sweep --param ppo.learning_rate=loguniform:1e-4:1e-3 --samples 8",),
    "study": (
        "snnkart study studies/sparsity.toml --out runs/sparsity",
        "snnkart study studies/small_S.toml --only 'small_S/*'",
    ),
    "plot": (f"snnkart plot raster {_RUN}/policy.nir",),
    "plot raster": (f"snnkart plot raster {_RUN}/policy.nir --step 20 --out raster.png",),
    "nir": ("snnkart nir info policy.nir",),
    "nir info": ("snnkart nir info policy.nir", "snnkart nir info model.nir --dt 1e-4 --json"),
    "nir run": ("snnkart nir run policy.nir --input currents.npy --check",),
    "nir manifest": ("snnkart nir manifest model.nir --env steer --dt 1e-4",),
    "ros": ("snnkart ros drive runs/gazebo-snn",),
    "track": ("snnkart track generate --seed 7 -o track.toml", "snnkart track edit my_track.toml"),
    "track generate": (
        "snnkart track generate --seed 7 -o track.toml",
        "snnkart track generate --seed 3 --kind course --length-m 14 -o c3.toml",
    ),
    "track show": (
        "snnkart track show track.toml -o track.png",
        "snnkart track show small_S --env gazebo --checkpoint -1 -o s.png",
    ),
    "ros sim": ("snnkart ros sim --policy runs/gazebo-snn",),
    "ros drive": ("snnkart ros drive runs/gazebo-snn/policy.nir --backend lava-sim",),
    "track edit": (
        "snnkart track edit my_track.toml",
        "snnkart track edit snnkart/tracks/small_S.toml",
    ),
}
"""Examples by command path ("" is ``snnkart`` itself); :func:`finish_help` requires one for
every command, so a new command cannot ship without."""


def tidy(text: str | None) -> str | None:
    """Help prose as the terminal should wrap it: paragraphs (blank-line separated) on one line
    each, without RST double backquotes, and safe from rich markup."""
    if text is None:
        return None
    paragraphs = re.split(r"\n\s*\n", text.strip())
    joined = "\n\n".join(" ".join(p.split()) for p in paragraphs)
    return escape(joined.replace("``", ""))


def _tidy_params(params: list[Any]) -> None:
    for param in params:
        param.help = tidy(getattr(param, "help", None))
        if isinstance(param, TyperOption) and param.is_bool_flag:
            param.metavar = ""  # a flag takes no value: no "<bool>"


class _Tidied:
    """Help tidied at construction (see the module docstring); a flag's help option takes no
    value, so it shows no metavar."""

    params: list[Any]

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["help"] = tidy(kwargs.get("help"))
        super().__init__(*args, **kwargs)
        _tidy_params(self.params)

    def get_help_option(self, ctx: Any) -> Any:
        option = super().get_help_option(ctx)  # type: ignore[misc]
        if option is not None:
            option.metavar = ""
        return option


class HelpCommand(_Tidied, TyperCommand):
    """A command whose help is tidied."""


class HelpGroup(_Tidied, TyperGroup):
    """A command group whose help is tidied."""


def _epilog(path: str) -> str:
    if path not in EXAMPLES:
        raise LookupError(f"snnkart {path}: add its examples to snnkart.cli.help.EXAMPLES")
    return escape("Examples:\n" + "\n".join(f"  {line}" for line in EXAMPLES[path]))


def finish_help(app: typer.Typer, path: str = "") -> None:
    """Give ``app``, its commands and its sub-groups their examples and tidy help."""
    app.info.cls = HelpGroup
    app.info.epilog = _epilog(path)
    for info in app.registered_commands:
        assert info.callback is not None
        name = info.name or info.callback.__name__.lower().replace("_", "-")
        info.cls = HelpCommand
        info.epilog = _epilog(f"{path} {name}".strip())
    for group in app.registered_groups:
        assert group.typer_instance is not None
        finish_help(group.typer_instance, f"{path} {group.name}".strip())
