"""Config keys that were renamed: the old name keeps loading (saved runs, old config files,
``--set``), with a warning where a user typed it."""

from __future__ import annotations

import warnings

RENAMED_KEYS: dict[tuple[str, str], str] = {("ppo", "num_steps"): "rollout_steps"}
"""Config keys that were renamed, ``(section, old) -> new``: the old name still loads (saved
runs, old config files, ``--set``), with a warning where a user typed it."""


def renamed_keys(data: dict[str, object], warn: bool) -> dict[str, object]:
    """``data`` with every renamed key under its new name; both names at once is an error."""
    for (section, old), new in RENAMED_KEYS.items():
        given = data.get(section)
        if not isinstance(given, dict) or old not in given:
            continue
        if new in given:
            raise ValueError(
                f"{section}.{old} is the old name of {section}.{new}; give only {section}.{new}"
            )
        if warn:
            warnings.warn(
                f"{section}.{old} is deprecated: it is now {section}.{new} (the old name still "
                "works for now)",
                FutureWarning,
                stacklevel=2,
            )
        given = {(new if k == old else k): v for k, v in given.items()}
        data = {**data, section: given}
    return data
