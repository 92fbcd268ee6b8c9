// Everything a node program uses: nodes, the scheduler, topics, services, time and units.
// Message types come from their generated headers (e.g. <horus/msg/cmd_vel.hpp>).
#pragma once

#include "horus/action.hpp"
#include "horus/clock.hpp"
#include "horus/codec.hpp"
#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/log.hpp"
#include "horus/msgpack.hpp"
#include "horus/network.hpp"
#include "horus/node.hpp"
#include "horus/run.hpp"
#include "horus/scheduler.hpp"
#include "horus/service.hpp"
#include "horus/topic.hpp"
#include "horus/topic_registry.hpp"
