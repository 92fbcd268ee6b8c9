"""The Python side of the parameter suite (test_params_e2e.py): test_nodes.ParamNodeBase,
generated from tests/schemas/test_nodes/param_node.hnode (the suite puts the generated package on
PYTHONPATH), run under the name given, ticking at 100 Hz until it is stopped or killed.

    python3 py_param_node.py NAME [PARAMS.yaml]

It prints what param_node.cpp prints, in the same form: `ready VALUES` after its first tick,
`tick VALUES` when a tick reads values that differ from the previous tick's, and `change NAME
VALUE SOURCE` for each write offered to on_param_change(); it refuses a gain above 5."""
from __future__ import annotations

import sys

import horus
import test_nodes


def shown(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return ",".join(shown(item) for item in value)
    if hasattr(value, "name"):  # an enum member
        return value.name
    return str(value)


class E2eParamNode(test_nodes.ParamNodeBase):
    def __init__(self, name: str) -> None:
        super().__init__(name=name)
        self.last_values = ""

    def current_values(self) -> str:
        p = self.params
        return " ".join(f"{name}={shown(getattr(p, name))}" for name in (
            "max_speed", "gain", "offset", "wheel_count", "enabled", "profile", "mode", "gains",
            "mask", "ticks"))

    def tick(self) -> None:
        values = self.current_values()
        if values != self.last_values:
            print("tick" if self.last_values else "ready", values, flush=True)
            self.last_values = values

    def on_param_change(self, change):
        print("change", change.name, shown(change.value), change.source, flush=True)
        if change.name == "gain" and change.value > 5:
            return horus.ParamVerdict.refuse("a gain above 5 makes the speed loop oscillate")
        return None


def main() -> int:
    if len(sys.argv) not in (2, 3):
        print(f"usage: {sys.argv[0]} NAME [PARAMS.yaml]", file=sys.stderr)
        return 2
    params = sys.argv[2] if len(sys.argv) == 3 else None
    try:
        scheduler = horus.Scheduler(tick_rate=100, params=params)
        scheduler.add(E2eParamNode(sys.argv[1]))
        scheduler.run()
    except horus.ParamError as error:
        print(error, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
