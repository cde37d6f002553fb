"""docs/bring_your_own_cta.md's worked example, run as written (with smaller budgets).

The blocks after ``<!-- own-anatomy:python -->`` and ``<!-- own-anatomy:bash -->`` are read
from the page, so the page and this test cannot drift apart: every command runs as a new
process in a fresh folder, and each budget this test shrinks must be found in the page.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "bring_your_own_cta.md"

#: Budget in the page -> the test's (the whole example then takes about a minute).
SMALLER = {
    "--frames 20000": "--frames 200 --set collector.init_random_frames=100 "
                      "--set collector.frames_per_batch=100 --set eval.trials=2 "
                      "--set eval.max_steps=40",
    "sim4endor evaluate runs/my_y": "sim4endor evaluate runs/my_y --trials 2 --no-progress",
    "--out my_y_expert.mp4": "--out my_y_expert.mp4 --width 160 --height 128",
    "--out my_y_sac.mp4": "--out my_y_sac.mp4 --max-steps 10 --width 160 --height 128",
}


def page_block(marker: str) -> str:
    """The fenced code block right after ``<!-- marker -->`` in the page."""
    found = re.search(rf"<!-- {marker} -->\s*```\w+\n(.*?)```", PAGE.read_text(), re.S)
    assert found, f"no block after <!-- {marker} --> in {PAGE}"
    return found.group(1)


def run(command: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, f"{shlex.join(command)}:\n{result.stderr[-3000:]}"
    assert "Traceback" not in result.stderr, result.stderr
    return result


@pytest.mark.render
def test_mesh_to_exported_policy_from_the_command_line(tmp_path: Path) -> None:
    (tmp_path / "experiments").symlink_to(ROOT / "experiments")
    (tmp_path / "make_mesh.py").write_text(page_block("own-anatomy:python"))
    run([sys.executable, "make_mesh.py"], tmp_path)
    script = page_block("own-anatomy:bash")
    for budget, smaller in SMALLER.items():
        assert budget in script, f"the page no longer says {budget!r}"
        script = script.replace(budget, smaller)
    outputs = []
    for line in script.strip().splitlines():
        words = shlex.split(line)
        if words[0] == "sim4endor":
            words = [sys.executable, "-m", "sim4endor", *words[1:]]
        elif words[0] == "python":
            words[0] = sys.executable
        outputs.append(run(words, tmp_path).stdout)
    build, reach, expert, train, evaluate, sac, export, robot = outputs
    assert float(re.search(r"lumen open ([0-9.]+)", build)[1]) >= 0.99
    assert re.search(r"inlet \([-0-9., ]+\) mm, targets \['T1', 'T2'\]", build)
    assert re.search(r"^T1 +2/2 successes", reach, re.M), reach
    assert re.search(r"^all +\d/4 successes", reach, re.M), reach
    assert expert.startswith("my_y_expert.mp4: success after")
    config = (tmp_path / "runs" / "my_y" / "config.yaml").read_text()
    assert f"vessel: {tmp_path / 'vessels_user' / 'my_y'}" in config and "target: T1" in config
    assert "wire: workhorse" in config
    assert json.loads(train.splitlines()[-1])["trials"] == 2
    assert re.search(r"^trials\s+2$", evaluate, re.M)
    assert sac.startswith("my_y_sac.mp4: ") and (tmp_path / "my_y_sac.mp4").stat().st_size > 0
    assert export.split() == [f"export/my_y/policy.{s}" for s in ("pt", "json", "onnx")]
    contract = json.loads((tmp_path / "export" / "my_y" / "policy.json").read_text())
    assert [e["name"] for e in contract["observation"]["entries"]] == ["tip_position",
                                                                       "tip_velocity"]
    assert contract["action"]["entries"][0]["scale"] == pytest.approx(1.5e-3)
    assert re.search(r"delta_insertion = [+-]\d\.\d{4} -> [+-]\d\.\d{3}e[+-]\d\d m", robot)
