"""A sigma-delta deployment's messages replayed on SANA-FE's Loihi model, each message a spike
event, on a tiny network counted by hand (in the worker subprocess, with a timeout). Needs the
``sanafe`` extra; without it the SANA-FE run skips as optional."""

from __future__ import annotations

import numpy as np
import pytest

from snnkart.energy.sanafe_model import SANAFE_PJ, sanafe_python
from snnkart.energy.sanafe_sigma_delta import job_of, per_inference, run_sd, sent_from_counts

SIZES = [3, 4, 2]  # input Delta 3 -> SigmaDelta 4 -> Sigma 2; held: L + 2 = 3 rows
SENT = [np.array([[1, 0, 1], [0, 0, 0], [0, 1, 0]], bool),  # the Delta's, per env step
        np.array([[1, 1, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0]], bool)]  # fmt: skip


def test_a_tiny_sigma_delta_replay_is_priced_as_counted_by_hand() -> None:
    python = sanafe_python()
    if python is None:
        pytest.skip("optional: SANA-FE is not installed (pip install 'snnkart[sanafe]')")
    weights = [np.arange(1, 13).reshape(4, 3), np.arange(1, 9).reshape(2, 4)]  # all positive
    job, arrays = job_of(SIZES, 3, weights, [np.zeros(4), np.zeros(2)], SENT)
    run = run_sd(job, arrays, python, timeout=120)
    # 3 Delta messages x fan-out 4 + 3 hidden messages x fan-out 2; one packet per message (one
    # destination core each), no hop (every group on tile 0)
    assert run["counts"]["synaptic_events"] == 18 and run["counts"]["packets"] == 6
    assert run["counts"]["hops"] == 0 and run["messages"] == [3, 3]
    # updates: a receiving neuron from the row its first input arrives (a spike sent at row r is
    # integrated at row r + 1), its potential never zero again (positive weights, no leak):
    # hidden 4 x (2 + 3 + 3) rows, Sigma 2 x (1 + 3 + 3) rows; the 6 replayed senders on top
    assert run["counts"]["neurons_updated"] - 6 == 4 * 8 + 2 * 7
    assert run["lif_neuron_rows"] == (4 + 2) * 3 * 3
    per = per_inference(run)
    e = per["energy_pj"]
    assert e["synapse"] == pytest.approx(18 * 35.5 / 3)
    assert e["network"] == pytest.approx(6 * 111.0 / 3)
    assert e["soma"] == pytest.approx((54 * 51.2 + 46 * 21.6) / 3)
    assert per["unexplained_pj"] == pytest.approx(0.0, abs=1e-9)
    # the hidden layer's 3 messages fired on the chip: the spike-out SANA-FE does not charge
    assert per["added_spike_out_pj"] == pytest.approx(3 * SANAFE_PJ["spike_out"] / 3)
    assert per["chip_pj"] == pytest.approx(e["total"] + per["added_spike_out_pj"])
    # the same messages given per row (layer i at row i) replay the same events
    rows = [np.zeros((3, 3, n), bool) for n in SIZES[:-1]]
    for i, s in enumerate(SENT):
        rows[i][:, i, :] = s
    by_row = run_sd(*job_of(SIZES, 3, weights, [np.zeros(4), np.zeros(2)], rows), python,
                    timeout=120)  # fmt: skip
    assert by_row["counts"] == run["counts"] and by_row["energy_j"] == run["energy_j"]


def test_masks_from_counts_and_refused_shapes() -> None:
    masks = sent_from_counts(np.array([[2, 1], [0, 4]]), SIZES)
    assert masks[0].tolist() == [[True, True, False], [False, False, False]]
    assert masks[1].sum(axis=1).tolist() == [1, 4]
    with pytest.raises(ValueError, match="does not fit sizes"):
        job_of(SIZES, 3, [np.zeros((3, 3)), np.zeros((2, 4))], [np.zeros(4), np.zeros(2)], SENT)
