"""snnkart's Adam is torch's, bit for bit, without importing torch._dynamo (snnkart/rl/optim.py)."""

from __future__ import annotations

import subprocess
import sys

import pytest
import torch

from snnkart.rl.optim import adam


def _net(seed: int) -> torch.nn.Module:
    torch.manual_seed(seed)
    return torch.nn.Sequential(torch.nn.Linear(5, 7), torch.nn.Tanh(), torch.nn.Linear(7, 2))


@pytest.mark.parametrize("foreach", [True, None])
def test_the_steps_equal_torchs_adam_bit_for_bit(foreach: bool | None) -> None:
    ours, theirs = _net(3), _net(3)
    opt_a = adam(ours.parameters(), lr=3e-3, eps=1e-5, foreach=foreach)
    opt_b = torch.optim.Adam(theirs.parameters(), lr=3e-3, eps=1e-5, foreach=foreach)
    gen = torch.Generator().manual_seed(0)
    for _ in range(25):
        x = torch.randn(16, 5, generator=gen)
        for net, opt in ((ours, opt_a), (theirs, opt_b)):
            opt.zero_grad()
            net(x).pow(2).sum().backward()
            opt.step()
    for a, b in zip(ours.parameters(), theirs.parameters(), strict=True):
        assert torch.equal(a, b)
    sa, sb = opt_a.state_dict(), opt_b.state_dict()
    assert sa["param_groups"] == sb["param_groups"]
    for k in sb["state"]:
        for name, value in sb["state"][k].items():
            assert torch.equal(sa["state"][k][name], value), name
    # checkpoints written by either load into the other
    torch.optim.Adam(_net(4).parameters(), lr=1.0).load_state_dict(sa)
    adam(_net(4).parameters(), lr=1.0, eps=1e-8, foreach=True).load_state_dict(sb)


@pytest.mark.timeout(120)
def test_a_training_step_does_not_import_torch_dynamo() -> None:
    code = (
        "import sys, torch\n"
        "from snnkart.rl.optim import adam\n"
        "net = torch.nn.Linear(3, 2)\n"
        "opt = adam(net.parameters(), lr=1e-3, eps=1e-5, foreach=True)\n"
        "opt.zero_grad(); net(torch.ones(4, 3)).sum().backward(); opt.step()\n"
        "opt.load_state_dict(opt.state_dict())\n"
        "assert 'torch._dynamo' not in sys.modules, 'torch._dynamo was imported'\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
