// The C++ side of the Python runtime's service tests.
//
//   horus_py_service_peer serve            serves pyrt_test.Add and Echo; prints "serving", stops
//                                          when stdin closes
//   horus_py_service_peer call A B TEXT    waits for a server, calls Add(A, B) and Echo(TEXT, 2)
//                                          and prints "sum TEXTTEXT", or the error of each call
#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>

#include <horus/service.hpp>
#include <pyrt_test/add.hpp>
#include <pyrt_test/echo.hpp>

namespace {

using namespace std::chrono_literals;
using horus::HandlerResult;
using pyrt_test::Add;
using pyrt_test::AddRequest;
using pyrt_test::AddResponse;
using pyrt_test::Echo;
using pyrt_test::EchoRequest;
using pyrt_test::EchoResponse;

int serve() {
  auto add = horus::ServiceServerBuilder<Add>()
                 .on_request([](const AddRequest& req) -> HandlerResult<AddResponse> {
                   if (req.a < 0) {
                     return "negative a: " + std::to_string(req.a);
                   }
                   return AddResponse{req.a + req.b};
                 })
                 .build();
  auto echo = horus::ServiceServerBuilder<Echo>()
                  .on_request([](const EchoRequest& req) -> HandlerResult<EchoResponse> {
                    if (req.text.empty()) {
                      return std::string("empty text");
                    }
                    std::string out;
                    for (std::uint32_t i = 0; i < req.repeat; ++i) out += req.text;
                    return EchoResponse{out};
                  })
                  .build();
  std::printf("serving\n");
  std::fflush(stdout);
  std::string line;
  while (std::getline(std::cin, line)) {
  }
  return 0;
}

int call(long long a, long long b, const std::string& text) {
  horus::ServiceClient<Add> add;
  horus::ServiceClient<Echo> echo;
  if (!add.wait_for_server(10s) || !echo.wait_for_server(10s)) {
    std::fprintf(stderr, "no server came\n");
    return 1;
  }
  const auto sum = add.call(AddRequest{a, b}, 5s);
  if (sum) {
    std::printf("%lld ", static_cast<long long>(sum->sum));
  } else {
    std::printf("error:%s ", sum.error().message().c_str());
  }
  const auto echoed = echo.call(EchoRequest{text, 2}, 5s);
  if (echoed) {
    std::printf("%s\n", echoed->text.c_str());
  } else {
    std::printf("error:%s\n", echoed.error().message().c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string role = argc > 1 ? argv[1] : "";
  if (role == "serve" && argc == 2) return serve();
  if (role == "call" && argc == 5) return call(std::stoll(argv[2]), std::stoll(argv[3]), argv[4]);
  std::fprintf(stderr, "usage: %s serve | call A B TEXT\n", argv[0]);
  return 2;
}
