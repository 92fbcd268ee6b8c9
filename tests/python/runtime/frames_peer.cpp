// The C++ side of the frame tests (test_runtime_frames.py): the robot's frames a C++ process
// sets, in the namespace of HORUS_NAMESPACE.
//
//   horus_py_frames_peer START_NS COUNT
//
// Sets base_link <- lidar static (0.2, 0, 0.1), a quarter turn about z; then map <- odom at 100 Hz:
// entry k (0 <= k < COUNT) at stamp START_NS + k * 10 ms, translation (0.1 k, 0, 0), a rotation
// of 0.01 k rad about z. Prints "ready" after the first entry and "done" after the last, then
// stays the authority of its frames until standard input closes. A refused write prints the
// error and exits with 1.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <string>
#include <thread>

#include <horus/frames.hpp>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: horus_py_frames_peer START_NS COUNT\n";
    return 2;
  }
  const std::chrono::nanoseconds start(std::stoll(argv[1]));
  const int count = std::stoi(argv[2]);
  constexpr std::chrono::milliseconds kPeriod(10);
  try {
    horus::FrameTree tree;
    tree.set_static_transform("base_link", "lidar",
                              {{0.2, 0, 0.1}, horus::axis_angle({0, 0, 1}, M_PI / 2)});
    const auto first = std::chrono::steady_clock::now();
    for (int k = 0; k < count; ++k) {
      std::this_thread::sleep_until(first + k * kPeriod);
      tree.set_transform("map", "odom", {{0.1 * k, 0, 0}, horus::axis_angle({0, 0, 1}, 0.01 * k)},
                         start + k * kPeriod);
      if (k == 0) std::cout << "ready" << std::endl;
    }
    std::cout << "done" << std::endl;
  } catch (const horus::Error& error) {
    std::cout << error.what() << std::endl;
    return 1;
  }
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  return 0;
}
