// Actions: long-running goals with feedback, cancellation and a result (everything of the
// actions API). An action is three generated services and three topics:
// runtime/src/action/README.md.
//
//   auto server = horus::ActionServerBuilder<Navigate>().on_execute(drive).build();
//   horus::ActionClient<Navigate> client;
//   auto goal = client.send_goal({.x = 2.0}, 1s, {.on_feedback = show});
//   auto outcome = goal->result(30s);
#pragma once

#include "horus/action_client.hpp"
#include "horus/action_server.hpp"
#include "horus/action_type.hpp"
