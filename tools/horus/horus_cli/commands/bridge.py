"""`horus bridge`: carries topics, services, actions and coordinate frames to and from Cyclone
DDS (other hosts, ROS 2) with the C++ DDS bridge (horus._core.dds.DdsBridge, run by horus.Network.serve on
this thread); this module parses its options."""
from __future__ import annotations

import signal
import threading

from horus_cli.common import EXIT_USAGE, CommandFailed, introspection, positive_float, positive_int


def bridge(args) -> int:
    if not introspection().has_dds():
        raise CommandFailed("this horus was built without Cyclone DDS (Debian: cyclonedds-dev), "
                            "so it has no bridge")
    from horus import Network
    export_frames = args.export_frames + (["*"] if args.frames else [])
    import_frames = args.import_frames + (["*"] if args.frames else [])
    if not (args.export or args.imports or args.export_service or args.import_service
            or export_frames or import_frames or args.export_action or args.import_action):
        raise CommandFailed("nothing to bridge: give --export and/or --import patterns (or "
                            "--export-service, --import-service, --export-frames, "
                            "--import-frames, --frames, --export-action, --import-action)",
                            EXIT_USAGE)
    deadlines = {}
    for given in args.deadline:
        pattern, _, milliseconds = given.rpartition("=")
        if not pattern or not milliseconds.isdigit() or int(milliseconds) < 1:
            raise CommandFailed(f"--deadline wants PATTERN=MS (a whole number of milliseconds, "
                                f"at least 1), got {given!r}", EXIT_USAGE)
        deadlines.setdefault(pattern, int(milliseconds))  # the first one counts
    try:
        network = Network(export=args.export, import_=args.imports, domain=args.domain,
                          reliable=not args.best_effort, depth=args.depth,
                          transient_local=args.transient_local, deadlines=deadlines,
                          export_services=args.export_service,
                          import_services=args.import_service,
                          service_timeout=args.service_timeout, ros2_types=args.ros2_types,
                          accept_untyped_writers=args.accept_untyped_writers,
                          export_frames=export_frames, import_frames=import_frames,
                          export_actions=args.export_action,
                          import_actions=args.import_action)
    except ValueError as error:
        raise CommandFailed(str(error), EXIT_USAGE) from None
    # SIGTERM stops the bridge as Ctrl+C does (status 0).
    stop = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        return network.serve(stop, args.namespace or "")
    except RuntimeError as error:
        raise CommandFailed(str(error)) from None
    finally:
        signal.signal(signal.SIGTERM, previous)


def register(commands) -> None:
    sub = commands.command("bridge", help="carry topics to and from Cyclone DDS (other hosts, "
                           "ROS 2)", parents=[commands.common],
                           description="Export local topics matching --export to DDS (as "
                                       "rt/<name>, each '.' a '/', in CDR) and import DDS "
                                       "topics matching --import into the namespace, until "
                                       "Ctrl+C. Nothing crosses that no pattern names "
                                       "(docs/dds-bridge.md).")
    sub.add_argument("--export", action="append", default=[], metavar="PATTERN",
                     help="local topics to write to DDS (a glob; repeatable)")
    sub.add_argument("--import", dest="imports", action="append", default=[], metavar="PATTERN",
                     help="DDS topics to publish locally, by their local name (rt/arm/state "
                          "is arm.state; a glob; repeatable)")
    sub.add_argument("--export-service", action="append", default=[], metavar="PATTERN",
                     help="local services to serve on DDS (rq/<name>Request, rr/<name>Reply)")
    sub.add_argument("--import-service", action="append", default=[], metavar="PATTERN",
                     help="services on DDS to serve locally (calls forwarded to their server)")
    sub.add_argument("--export-action", action="append", default=[], metavar="PATTERN",
                     help="local actions to serve to ROS 2 action clients on DDS "
                          "(rq/<name>/_action/send_goalRequest, rt/<name>/_action/status, ...)")
    sub.add_argument("--import-action", action="append", default=[], metavar="PATTERN",
                     help="ROS 2 action servers on DDS to serve to local action clients (goals "
                          "forwarded to them)")
    sub.add_argument("--domain", type=int, default=0, help="the DDS domain id (default 0)")
    sub.add_argument("--best-effort", action="store_true",
                     help="best-effort DDS endpoints (default: reliable)")
    sub.add_argument("--depth", type=positive_int, default=100,
                     help="DDS history depth of each writer and reader (default 100)")
    sub.add_argument("--transient-local", action="append", default=[], metavar="PATTERN",
                     help="latched topics: a DDS reader that joins later gets the last message "
                          "(default: volatile; an importing bridge follows the writer)")
    sub.add_argument("--deadline", action="append", default=[], metavar="PATTERN=MS",
                     help="topics that must carry a message every MS milliseconds; each missed "
                          "deadline is said on stderr (default: none; an importing bridge "
                          "follows the writer)")
    sub.add_argument("--service-timeout", type=positive_float, default=10.0, metavar="SECONDS",
                     help="how long an exported service's local server has to answer a call "
                          "from DDS (default 10); the caller then gets Timeout")
    sub.add_argument("--ros2-types", action="append", default=[], metavar="PATTERN",
                     help="topics that cross as their standard type's ROS 2 twin (CmdVel as "
                          "geometry_msgs/msg/Twist, Imu, LaserScan, Odometry, ...), both ways")
    sub.add_argument("--accept-untyped-writers", action="store_true",
                     help="import from DDS writers that announce no XTypes type information "
                          "(ROS 2 nodes), whose type DDS cannot check (default: refused)")
    sub.add_argument("--export-frames", action="append", default=[], metavar="PATTERN",
                     help="child frames of the namespace's frame tree to write to DDS as ROS 2's "
                          "/tf and /tf_static (tf2_msgs/msg/TFMessage; a glob; repeatable)")
    sub.add_argument("--import-frames", action="append", default=[], metavar="PATTERN",
                     help="child frames to read from DDS's /tf and /tf_static into the frame "
                          "tree (a glob; repeatable); the bridge becomes their authority")
    sub.add_argument("--frames", action="store_true",
                     help="every frame both ways: --export-frames '*' --import-frames '*' "
                          "(a frame the bridge imported is never exported)")
    sub.set_defaults(handler=bridge)
