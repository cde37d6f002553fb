"""The probing expert's profile splits an episode into its probes, screens and the rest."""

from __future__ import annotations

from pathlib import Path

import pytest
from guidewire_helpers import write_tube_vessel
from script_helpers import load_script

from sim4endor.physics import GuidewirePhysics
from sim4endor.rl import baselines, generalisation
from sim4endor.tasks.expert import ProbeConfig, ProbingExpert

profile = load_script("experiments/benchmarks/probing_profile.py")


class _ProbesAtOnce(ProbingExpert):
    """Stuck from its first step: one probe of one aim, three steps ahead."""

    def __init__(self) -> None:
        super().__init__(probe=ProbeConfig(roll_offsets_deg=(0.0,), horizon=3, stall_steps=0,
                                           max_probes=1, pull_back=False))


def test_an_episode_is_split_into_probes_screens_and_the_rest(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(baselines, "ProbingExpert", _ProbesAtOnce)
    vessel = str(write_tube_vessel(tmp_path / "tube").root)
    step = GuidewirePhysics.step
    config = generalisation.SuiteConfig(trials=1, max_steps=12)
    runs = [profile.profile_vessel(vessel, config=config)[0] for _ in range(2)]
    assert GuidewirePhysics.step is step  # the counting is undone
    row = runs[0]
    assert row["target"] == "A" and row["probes"] == 1
    steps, physics = row["control_steps_by_part"], row["physics_steps_by_part"]
    assert steps["episode"] == 12 and 1 <= steps["probe"] <= 3
    # Every step outside the probe's plan is screened once, or more for a fallback.
    assert steps["screen"] >= 12 - steps["probe"]
    substeps = physics["episode"] / steps["episode"]
    assert substeps > 1 and all(physics[p] == substeps * steps[p] for p in profile.PARTS)
    assert sum(row["cpu_s_by_part"].values()) == pytest.approx(row["cpu_s"])
    assert min(row["cpu_s_by_part"].values()) >= 0 and row["copies"] >= steps["screen"]
    assert runs[1]["actions_sha1"] == row["actions_sha1"]  # the same decisions
    assert profile.describe(profile.total(runs)).startswith("| all | 2 episodes | 1.2 | 24 | 2 |")
