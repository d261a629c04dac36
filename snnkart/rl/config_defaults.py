"""Training defaults that differ by policy kind, and by env and policy kind: applied by
:class:`snnkart.rl.config.TrainConfig` only where the user set nothing. Each says why, with the
result that showed it (docs/results.md lists the result files).
"""

from __future__ import annotations

from typing import Any

POLICY_DEFAULTS: dict[str, dict[str, dict[str, Any]]] = {
    # surrogate-gradient SNNs learn faster with a larger step
    "snn": {"ppo": {"learning_rate": 1e-3}},
    # The ANN actor and critic are as wide as the SNN actor (64-64), a like-for-like comparison;
    # it also learned more reliably than 128-128 (gazebo seed 1: first finish 100k instead of
    # 217k). The SNN's critic keeps ann.hidden = 128-128.
    "ann": {"ann": {"hidden": (64, 64)}},
    # The sigma-delta actor is the ANN's ReLU MLP with the chip's integers faked in: the ANN's
    # critic width (not measured for sdnn separately).
    "sdnn": {"ann": {"hidden": (64, 64)}},
}


ENV_POLICY_DEFAULTS: dict[tuple[str, str], dict[str, dict[str, Any]]] = {
    # (The result files named below are in the checkout's benchmark results; see docs/results.md.)
    # Gazebo's turns take many steps of one key (each step changes the speed OR the turn
    # rate): more exploration finds them (bench_learning-0861f38-*.json:
    # 3/3 seeds for the ANN at 0.02); grid and steer stay more random than they should at 0.02.
    ("gazebo", "ann"): {"ppo": {"learning_rate": 1e-3, "ent_coef": 0.02}},
    # The gazebo SNN learned slower than the ANN and finished in 2 of seeds 1-3 with 8 envs x
    # 256 steps; the same batch from 16 envs x 128 steps (more, shorter episodes' worth of
    # starts per update) met the targets in 5 of seeds 1-5, where 8 envs met them in 4 and
    # 32 x 64 failed seed 1 (bench_learning-*-gazebo-snn-envs.json).
    ("gazebo", "snn"): {"ppo": {"ent_coef": 0.02, "num_envs": 16, "rollout_steps": 128}},
    # The steer ANN stopped short of the first hairpin in 2 of 3 seeds at 0.01 and finished
    # it in both at 0.02 (bench_learning-54afbe7-steer-ann-ent0.02.json;
    # 3/3 in bench_learning-d87ccc1).
    ("steer", "ann"): {"ppo": {"ent_coef": 0.02}},
    # Grid's impulse actions explore well, and a large entropy bonus leaves a mixture whose
    # argmax clips corners (eval 75-85 % in 4 of 6 runs at 0.01; 90-100 % in all 6 at 0:
    # bench_learning-d87ccc1 and -ec5cb07). But with none, the ANN got
    # stuck wandering in 1 of 5 seeds (bench_learning-0b2f812); a small floor, 0.005, found
    # the first finish in 10 of 10 seeds, eval 78-96 % (study-6f4d45b-grid-ent0.005). The
    # SNN learned in 5 of 5 seeds without one, sooner than in 10 of 10 with it.
    # Grid's actions push in fixed world directions, so each corner of a loop is a new
    # manoeuvre, learned only once the kart reaches it: on the held-out ring 7/10 ANN and 7/10
    # SNN seeds first finished within 300k steps (held-out-de61c27-ring-grid). Half the training
    # episodes starting just past a random checkpoint (snnkart.envs.starts): 10/10 and 10/10,
    # median first finish 51k and 49k instead of 192k and 223k (screen-2f7c1ad-ring-grid-
    # spread50; a quarter: 10/10, 69k and 105k, -spread25). A route clearance of 0.30 m gave
    # 9/10 and 8/10, a stall term of 0.03 7/10 and 4/10 (screen-de61c27-ring-grid-*).
    ("grid", "ann"): {"ppo": {"ent_coef": 0.005, "start_spread": 0.5}},
    ("grid", "snn"): {"ppo": {"ent_coef": 0.0, "start_spread": 0.5}},
}
# The sdnn actor is the ANN's network quantised: it starts from the ANN's per-env settings
# (not tuned for sdnn separately yet).
ENV_POLICY_DEFAULTS.update(
    {
        (env, "sdnn"): values
        for (env, kind), values in list(ENV_POLICY_DEFAULTS.items())
        if kind == "ann"
    }
)
