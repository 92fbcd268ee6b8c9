"""The README's parameter example (readme_params.cpp, cut out of README.md by CMake) does what
the README's console block says: a write is seen by the next tick, a write the node vetoes and one
outside the declared range are refused with those reasons, and a dump is a YAML file."""
from __future__ import annotations

import os

import yaml
from conftest import run_horus


def test_the_readme_example_answers_as_the_readme_shows(children_with_stderr):
    motor = children_with_stderr.start([os.environ["HORUS_README_PARAMS"]])
    motor.errors.wait_for("max speed now 0.50 m/s")

    accepted = run_horus("param", "set", "motor", "max_speed", "0.8")
    assert (accepted.returncode, accepted.stdout) == (0, "motor.max_speed = 0.8 (version 2)\n")
    motor.errors.wait_for("max speed now 0.80 m/s")

    vetoed = run_horus("param", "set", "motor", "max_speed", "1.5")
    assert (vetoed.returncode, vetoed.stderr) == (
        1, "horus: motor.max_speed refused: node motor refused: above 1 m/s needs the cage "
           "closed\n")
    outside = run_horus("param", "set", "motor", "max_speed", "7")
    assert (outside.returncode, outside.stderr) == (
        1, "horus: motor.max_speed refused: parameter 'max_speed': 7 is above the maximum 2\n")

    dumped = run_horus("param", "dump")
    assert yaml.safe_load(dumped.stdout) == {"motor": {"max_speed": 0.8}}
