"""The two PPO losses of one minibatch, as plain functions of tensors (what
:meth:`snnkart.rl.ppo.Trainer.update` minimises, with the entropy bonus and the rate penalty).

Clipped surrogate (Schulman et al. 2017, eq. 7), with ``r = exp(log_prob - old_log_prob)`` and
the advantages ``A`` normalised over the minibatch (``norm_adv``)::

    L_clip = mean( max(-A * r, -A * clip(r, 1 - eps, 1 + eps)) )

A sample whose ratio has left ``[1 - eps, 1 + eps]`` in the direction its advantage favours
takes the clipped term, which is constant: it contributes no gradient.
"""

from __future__ import annotations

import torch


def normalise_advantages(advantages: torch.Tensor) -> torch.Tensor:
    """Zero mean, unit (sample) standard deviation over the tensor given: one minibatch."""
    return (advantages - advantages.mean()) / (advantages.std() + 1e-8)


def clipped_surrogate(
    log_prob: torch.Tensor,
    old_log_prob: torch.Tensor,
    advantages: torch.Tensor,
    clip_coef: float,
    norm_adv: bool,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The policy loss ``L_clip`` of one minibatch, the ratios ``r`` and their logarithms.

    ``log_prob`` is the current policy's log-probability of each stored action ``[B]``,
    ``old_log_prob`` the one stored at rollout time, ``advantages`` the GAE advantages ``[B]``
    (normalised here, over this minibatch, when ``norm_adv``)."""
    logratio = log_prob - old_log_prob
    ratio = logratio.exp()
    adv = normalise_advantages(advantages) if norm_adv else advantages
    pg_loss = torch.max(-adv * ratio, -adv * ratio.clamp(1 - clip_coef, 1 + clip_coef)).mean()
    return pg_loss, ratio, logratio


def value_loss(
    value: torch.Tensor,
    old_value: torch.Tensor,
    returns: torch.Tensor,
    clip_coef: float,
    clip_vloss: bool,
) -> torch.Tensor:
    """Half the mean squared error of the value head against the returns; with ``clip_vloss``
    the larger of it and the error of a prediction kept within ``clip_coef`` of ``old_value``."""
    if clip_vloss:
        v_clipped = old_value + (value - old_value).clamp(-clip_coef, clip_coef)
        return 0.5 * torch.max((value - returns) ** 2, (v_clipped - returns) ** 2).mean()
    return 0.5 * ((value - returns) ** 2).mean()
