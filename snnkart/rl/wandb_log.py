"""The optional Weights & Biases logger (``snnkart train --wandb``, the ``wandb`` extra).

It logs what TensorBoard gets, under the same names: every key of an iteration's metrics
record that has a ``/`` in it (``charts/episodic_return``, ``losses/approx_kl``, ...), at the
run's global step; the resolved config goes to the W&B run's config. W&B's own settings apply:
``WANDB_MODE=offline`` keeps the run on disk (``wandb sync`` uploads it later), ``WANDB_PROJECT``
names the project (default ``snnkart``); the files go under ``run_dir/wandb/`` unless
``WANDB_DIR`` says otherwise.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from snnkart.errors import UsageError

INSTALL_HINT = "--wandb needs the wandb extra: pip install 'snnkart[wandb]'"


def require_wandb() -> None:
    """Raise a one-line install hint when the ``wandb`` package is not installed."""
    try:
        import wandb  # noqa: F401
    except ImportError:
        raise UsageError(INSTALL_HINT) from None


class WandbLogger:
    """One W&B run beside a training run's TensorBoard scalars."""

    def __init__(self, run_dir: Path, config: dict[str, object]) -> None:
        require_wandb()
        import wandb

        run_dir = Path(run_dir)
        where = Path(os.environ.get("WANDB_DIR") or run_dir)
        where.mkdir(parents=True, exist_ok=True)
        self.run = wandb.init(
            project=os.environ.get("WANDB_PROJECT", "snnkart"),
            name=run_dir.name,
            dir=str(where),
            config=config,
        )

    def log(self, record: Mapping[str, float | None], global_step: int) -> None:
        """Log the record's scalars (the keys TensorBoard gets) at ``global_step``."""
        scalars = {k: v for k, v in record.items() if "/" in k and v is not None}
        self.run.log(scalars, step=global_step)

    def close(self) -> None:
        self.run.finish()
