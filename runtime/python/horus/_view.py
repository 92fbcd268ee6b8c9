"""horus.View: the live view served from inside a scheduler's process (docs/live-view.md).

The C++ live view (horus::LiveView, bridges/view/) runs on threads of the scheduler's own process,
as SchedulerConfig::view() runs it for a C++ program; this class only holds its options.
"""
from __future__ import annotations

import ipaddress


class View:
    """Serves the scheduler's namespace to Foxglove, Lichtblick and the built-in page over the
    Foxglove WebSocket protocol while the scheduler lives, as `horus view` does.

    `listen` is the address listened on (127.0.0.1, this machine only, by default), `port` the
    TCP port (0: any free one; the scheduler prints `live view: ws://ADDR:PORT/` once listening),
    `discovery_interval` how often (seconds) the namespace is looked at for topics and services
    that came or went.
    """

    def __init__(self, port: int = 8765, listen: str = "127.0.0.1",
                 discovery_interval: float = 0.25) -> None:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ValueError(f"port must be a TCP port (0..65535, 0: any free one), got {port!r}")
        try:
            ipaddress.ip_address(listen)
        except ValueError:
            raise ValueError(f"listen must be an IP address of this machine, got {listen!r}") \
                from None
        if not float(discovery_interval) >= 0.001:
            raise ValueError(
                f"discovery_interval must be at least 0.001 s, got {discovery_interval!r}")
        self.port = port
        self.listen = listen
        self.discovery_interval = float(discovery_interval)

    def __repr__(self) -> str:
        return (f"View(port={self.port}, listen={self.listen!r}, "
                f"discovery_interval={self.discovery_interval})")

    def _options(self) -> tuple[str, int, float]:
        """What horus._core.Scheduler's `view` keyword takes."""
        return (self.listen, self.port, self.discovery_interval)


def view_options(view) -> tuple[str, int, float] | None:
    """Scheduler(view=...)'s value as the core's options: None, True (the defaults), a port
    number or a horus.View."""
    if view is None or view is False:
        return None
    if view is True:
        return View()._options()
    if isinstance(view, int) and not isinstance(view, bool):
        return View(port=view)._options()
    if isinstance(view, View):
        return view._options()
    raise TypeError(f"view takes True, a port number or a horus.View, got {type(view).__name__}")
