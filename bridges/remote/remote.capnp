# The remote link of HORUS (`horus remote`, bridges/remote/): what a peer outside the robot's LAN
# sees once TLS has authenticated it. The bootstrap capability of a connection is its Session,
# made for the peer's certificate name and limited by the server's policy for that name.
@0xfcc427978d17cc8c;

$import "/capnp/c++.capnp".namespace("horus::remote::wire");

struct TopicInfo {
  name @0 :Text;
  type @1 :Text;
  fingerprint @2 :UInt64;
  # The canonical schema text of the type (what a topic segment stores).
  schema @3 :Text;
  isPod @4 :Bool;
  # Payload bytes per slot: the exact size of a POD message, the limit of a serialized one.
  maxMessageSize @5 :UInt32;
  capacity @6 :UInt32;
  # What the peer may do with the topic (Session.topics sets them; elsewhere unused).
  mayRead @7 :Bool;
  mayWrite @8 :Bool;
  # The type description (MessagePack, "horus.typedesc", docs/type-description.md: the type's
  # fields with offsets, defaults and units) as the topic's segment records it, so that a topic
  # the far end makes has it too. Empty from a peer older than it, or for a type without one.
  description @9 :Data;
}

# Where messages of one topic go: the robot streams a subscription into the peer's Sink, the
# peer streams what it publishes into the robot's. Each message is HORUS's own bytes (a POD's
# bytes, or the serialized encoding). Dropping the capability ends the stream.
interface Sink {
  # `sequence`: the message's ticket on the sending side's topic, the number its ring gave it as
  # it was published (every message published on the topic has the next one, whoever published
  # it), so a message the stream left out shows as a gap; `dropped`: messages the sender left
  # out of this stream so far because it was slower than the publisher (latest wins), at least
  # the gaps before this message. A frame of a pool-backed type (Image, DepthImage, PointCloud,
  # Tensor) is its descriptor, whose `block` is zeros, followed by the descriptor's `data_size`
  # bytes of its block (docs/remote.md, "The wire, for other clients").
  message @0 (sequence :UInt64, dropped :UInt64, data :Data) -> stream;
}

# A live service of the robot the peer may call: the type of its request frames (the robot's
# `<name>.request` topic) and the identity its server registered.
struct ServiceInfo {
  name @0 :Text;
  request @1 :TopicInfo;
  requestType @2 :Text;
  responseType @3 :Text;
  fingerprint @4 :UInt64;
  # The type of its response frames (a reply topic's), when the robot has one: the peer makes
  # a caller's reply topic with it when the caller has not (`horus service call` does not).
  response @5 :TopicInfo;
}

# A subscription lasts as long as the peer holds this capability.
interface Subscription {
  # Messages streamed and dropped so far.
  stats @0 () -> (sent :UInt64, dropped :UInt64);
}

interface Session {
  # The topics of the robot's namespace the peer may read or write, with their types.
  topics @0 () -> (topics :List(TopicInfo));

  # Streams `topic` into `sink`, at most `queue` messages behind (latest wins beyond that, and
  # beyond 16 MiB queued for all the peer's subscriptions). `type` and `fingerprint` are what
  # the peer expects: another type is refused, naming both. A peer holds at most 4
  # subscriptions and publishes of one topic and 64 in all (over all its connections); more
  # are refused (docs/remote.md, "What an authenticated peer can do").
  subscribe @1 (topic :Text, type :Text, fingerprint :UInt64, sink :Sink, queue :UInt32)
      -> (subscription :Subscription);

  # A sink for `topic` on the robot, created with `info`'s type when it does not exist; a topic
  # of another type (name, fingerprint, a POD's size) is refused, naming both. Counts as a
  # subscription does against the peer's limits.
  publish @2 (info :TopicInfo) -> (sink :Sink);

  # The robot's live services the peer may call.
  services @3 () -> (services :List(ServiceInfo));

  # Hands a request frame (HORUS's own bytes, as the peer's client sent it) to the robot's
  # server under ids of the robot's, and its response frame back. `response` of the params: the
  # type of the response frames, unset when the peer does not know it (the robot then takes it
  # from a reply topic of its own, or from the one its server makes to answer). A call the
  # robot's server did not answer has an empty `response` and a `failure` saying why, of the
  # kind a client on the robot would have got. `responseType`: the type of the response frames,
  # set whenever the robot knows it (always with a response).
  call @4 (service :Text, request :Data, response :TopicInfo, timeoutMs :UInt32)
      -> (response :Data, failure :CallFailure, responseType :TopicInfo);

  # The parameters of the robot's running nodes the peer may see (`PEER param NODE.PARAMETER`
  # rules): a node none of whose parameters it may see is left out. Answered once the robot's
  # `generation` (a digest of which nodes run and of their change counts) differs from `since`,
  # or after `waitMs` (at most 10 s) when nothing changed: the peer follows changes by asking
  # again with the generation it was given.
  params @5 (since :UInt64, waitMs :UInt32) -> (generation :UInt64, nodes :List(ParamNode));

  # Writes one parameter through its owner on the robot, as `horus param set` there would, with
  # "remote:PEER" as the change's source. A refusal (the policy's, the declaration's, the
  # owner's) is `accepted` false with the reason; `version` is the parameter's after the write.
  setParam @6 (node :Text, name :Text, value :Data, timeoutMs :UInt32)
      -> (accepted :Bool, reason :Text, version :UInt64);

  # Streams the robot's coordinate frames whose child matches one of `patterns` (globs) and
  # that the policy lets the peer read (`PEER read @frames/CHILD` rules; no other frame of the
  # tree shows) into `sink`: first every such frame's newest dynamic transform and the whole
  # static set, then each new dynamic transform and the static set again whenever it changes.
  # Frames this peer set on the robot (setFrames) are not sent back to it. `dropped` of the
  # subscription's stats: dynamic transforms left out because the peer was slower than the
  # robot's writers. Counts against the peer's limits as a subscription of a topic "@frames".
  frames @7 (patterns :List(Text), sink :FrameSink) -> (subscription :Subscription);

  # Sets frames in the robot's tree, the robot's serving process being their authority there:
  # `dynamic` transforms each child's oldest first (a stamp not newer than the child's newest
  # set this way is skipped), `statics` held at every time. A frame the policy does not let
  # the peer write (`PEER write @frames/CHILD`), or that the robot's tree refuses (another
  # authority, a cycle, not a rotation), is left out and named in `refusals` with the reason.
  setFrames @8 (dynamic :List(FrameTransform), statics :List(FrameTransform))
      -> (refusals :List(FrameRefusal));

  # Answers once the robot's server of `service` (one the peer may call) that serves it now is
  # gone: withdrawn, replaced by another instance, or its process exited (`why` says which); at
  # once when it has none. The robot looks every 10 ms, as an action's client looks at its
  # server: a laptop that stands in for an action's send_goal withdraws its stand-in then, so that
  # the goals of its local clients end (aborted) at once rather than at their own timeouts.
  serverGone @9 (service :Text) -> (why :Text);
}

# One transform of a frame tree: the child frame's pose in its parent at `stamp` (ns since the
# Unix epoch; unused for a static transform), `rotation` applied first, then `translation`.
struct FrameTransform {
  parent @0 :Text;
  child @1 :Text;
  stamp @2 :Int64;
  translation @3 :Vector3;
  rotation @4 :Quaternion;
}

struct Vector3 {
  x @0 :Float64;
  y @1 :Float64;
  z @2 :Float64;
}

# A unit quaternion (x, y, z, w).
struct Quaternion {
  x @0 :Float64;
  y @1 :Float64;
  z @2 :Float64;
  w @3 :Float64 = 1;
}

# Where the robot's frames go (Session.frames).
interface FrameSink {
  # New dynamic transforms, each child's oldest first; with `staticsChanged`, `statics` is the
  # whole static set the peer may see now (it may be empty).
  transforms @0 (dynamic :List(FrameTransform), statics :List(FrameTransform),
                 staticsChanged :Bool) -> stream;
}

# A frame Session.setFrames did not set, and why (the policy's refusal names the policy).
struct FrameRefusal {
  child @0 :Text;
  reason @1 :Text;
}

# One node's parameters as a peer may see them.
struct ParamNode {
  node @0 :Text;
  # The declarations of the parameters the peer may see: a type description (MessagePack,
  # "horus.typedesc", docs/type-description.md) whose root message has one field per parameter
  # with its declaration keys (doc, range, choices, read_only), as the robot's store holds it.
  description @1 :Data;
  values @2 :List(ParamValue);
}

struct ParamValue {
  name @0 :Text;
  # MessagePack bytes of the type description's VALUE (an enum's is its enumerator's name).
  value @1 :Data;
  # 1 for the value the node started with, +1 for each accepted write.
  version @2 :UInt64;
}

# Why the robot's server gave no answer to a call; `text` as a client on the robot would read it.
struct CallFailure {
  kind @0 :Kind;
  text @1 :Text;

  enum Kind {
    # Answered (the failure is unset).
    none @0;
    # No server of the service on the robot.
    noServer @1;
    # No answer within the call's timeout.
    timeout @2;
    # The request or its answer was lost (the server died, stopped or was restarted).
    transport @3;
  }
}
