#include <cstdio>

#include <robot_base/point.hpp>

int main() {
  robot_base::Point point{};
  point.x = 1.5;
  std::printf("%s\n", point.log_summary().c_str());
}
