"""The physics profile benchmark runs and splits a step into MuJoCo's stages."""

from __future__ import annotations

from script_helpers import load_script

convergence = load_script("experiments/benchmarks/guidewire_convergence.py")
profile = load_script("experiments/benchmarks/physics_profile.py")


def test_a_case_is_profiled_stage_by_stage() -> None:
    case = {c.name: c for c in convergence.CASES["full"]}["simplified_phantom_task_a"]
    row = profile.profile(case, None)
    assert row["env_steps"] > 10 and row["env_steps_per_cpu_s"] > 0
    shares = row["share_percent"]
    assert set(shares) == set(profile.STAGES)
    assert all(share >= 0 for share in shares.values()) and 50 < sum(shares.values()) <= 100.5
    assert row["newton_iterations"] >= 1 and row["nv"] > 0
