// The C++ twin of test_record_frames.py's Python writer: sets the static lidar, says "ready",
// waits for a line on stdin (the recorder is following the tree by then), then moves the robot
// at 100 Hz (odom drifts in the map, base_link turns in odom) and says "done".
//
//   frames_writer UPDATES
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <thread>

#include "horus/frames.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: frames_writer UPDATES\n");
    return 2;
  }
  const int updates = std::atoi(argv[1]);
  horus::FrameTree tree;
  tree.set_static_transform("base_link", "lidar",
                            {{0.2, 0.0, 0.1}, {0, 0, std::sin(0.2), std::cos(0.2)}});
  std::printf("ready\n");
  std::fflush(stdout);
  std::string line;
  std::getline(std::cin, line);
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < updates; ++i) {
    const std::chrono::nanoseconds stamp = std::chrono::system_clock::now().time_since_epoch();
    const double a = i * 0.01;
    tree.set_transform("map", "odom",
                       {{1.0 + 0.1 * a, 0.5 * a, 0.0}, {0, 0, std::sin(a / 8), std::cos(a / 8)}},
                       stamp);
    tree.set_transform("odom", "base_link",
                       {{a, 0.2 * a * a, 0.0}, {0, 0, std::sin(a / 2), std::cos(a / 2)}}, stamp);
    std::this_thread::sleep_until(start + std::chrono::milliseconds(10 * (i + 1)));
  }
  std::printf("done\n");
  return 0;
}
