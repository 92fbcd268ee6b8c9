// horus::run: the one-liner for programs that create every node upfront (seed 001's horus.run).
//
//   return horus::run({horus::RunNode(lidar).order(10).rate(40_hz),
//                      horus::RunNode(motor).order(20).rate(1000_hz).budget(300_us),
//                      logger},  // default settings
//                     horus::SchedulerConfig{}.rt(true).watchdog(500_ms));
//
// Use a Scheduler instead for runtime changes (adding or removing nodes, rates), tick_once() in
// tests, or to inspect metrics after the run.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "horus/node.hpp"
#include "horus/scheduler.hpp"

namespace horus {

/// Builds a Scheduler from `config`, adds and builds every node in the given order, then runs
/// until stop (Ctrl+C, SIGTERM, a node's request_stop(), a fatal failure) or for `duration`.
/// Returns what Scheduler::run() returns; throws horus::Error for an invalid node or setting.
int run(std::vector<RunNode> nodes, SchedulerConfig config = {},
        std::optional<std::chrono::nanoseconds> duration = std::nullopt);

}  // namespace horus
