"""Child-process scripts that several suites share: the same behaviour (topics in order, a service
with a failing case, a node with parameters) checked through the command, the bridges and the
remote link, so one copy of each."""


# The end of a subscriber script that defines `count`, `capacity` and `wanted` (topic name ->
# (message type, key), key(message) -> (sequence number, whether its content matches it)): takes
# the first `count` messages of each topic named in argv[2:] and prints "<topic> <seq> ..." (-1
# for a message whose content does not match its number).
RECEIVE_IN_ORDER = """
topics = {name: (horus.Topic(wanted[name][0], name, capacity=capacity), wanted[name][1])
          for name in sys.argv[2:]}
print("ready", flush=True)
got = {name: [] for name in topics}
while any(len(seen) < count for seen in got.values()):
    idle = True
    for name, (topic, key) in topics.items():
        message = topic.try_recv()
        if message is not None and len(got[name]) < count:
            idle = False
            number, intact = key(message)
            got[name].append(number if intact else -1)
    if idle:
        time.sleep(0.001)
for name, seen in got.items():
    print(name, *seen, flush=True)
"""


def scale_server(package: str) -> str:
    """Serves `package`.Scale until killed, printing "ready" once serving; a factor of 0 is the
    handler's failure."""
    return f"""
import time, horus
from {package} import Scale, ScaleResponse
""" + """
def handle(request):
    if request.factor == 0:
        raise ValueError("a factor of 0")
    return ScaleResponse(product=request.value * request.factor,
                         note=f"{request.value:g} times {request.factor:g}")
server = horus.ServiceServer(Scale, handle)
print("ready", flush=True)
while True:
    time.sleep(1)
"""


def param_motor(*extra: str) -> str:
    """A Python program running node "motor" at 100 Hz with parameters max_speed (f64, 0 to 2 m/s),
    profile ("eco", "sport" or "track") and gains ([f64; 3]), then one declaration per `extra`
    (`self.declare_param(...)` lines); it prints "ready" on its first tick, refuses the "track"
    profile ("track mode needs the cage closed") and prints "change NAME VALUE SOURCE" for each
    change it accepts."""
    declarations = "".join(f"\n        {line}" for line in extra)
    return f"""
import horus

class Motor(horus.Node):
    def __init__(self):
        super().__init__(name="motor", rate=100)
        self.declare_param("max_speed", 1.0, min=0.0, max=2.0, unit="m/s",
                           doc="Top speed the planner may command.")
        self.declare_param("profile", "eco", choices=["eco", "sport", "track"])
        self.declare_param("gains", [1.0, 0.5, 0.0]){declarations}
        self.ticks = 0

    def tick(self):
        self.ticks += 1
        if self.ticks == 1:
            print("ready", flush=True)

    def on_param_change(self, change):
        if change.name == "profile" and change.value == "track":
            return horus.ParamVerdict.refuse("track mode needs the cage closed")
        print(f"change {{change.name}} {{change.value!r}} {{change.source}}", flush=True)

horus.Scheduler(tick_rate=100).add(Motor()).run()
"""
