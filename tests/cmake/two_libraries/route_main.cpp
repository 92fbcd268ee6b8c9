#include <cstdio>

#include <robot_app.hpp>

int main() {
  robot_app::Route route{};
  route.goal.y = 4.0;
  route.speed = 0.5F;
  std::printf("%s\n", route.log_summary().c_str());
}
