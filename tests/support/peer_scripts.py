"""Child-process scripts that the dds and remote suites share: the same behaviour (topics in
order, a service with a failing case) checked over two transports, so one copy of each."""


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
