// Services: request/response between nodes and processes (everything of the services API).
//
//   auto server = horus::ServiceServerBuilder<AddInts>()
//                     .on_request([](const AddIntsRequest& r) { return AddIntsResponse{r.a + r.b};
//                     }) .build();
//   horus::ServiceClient<AddInts> client;
//   horus::ServiceResult<AddIntsResponse> sum = client.call({2, 3}, 100ms);
#pragma once

#include "horus/service_async.hpp"
#include "horus/service_client.hpp"
#include "horus/service_error.hpp"
#include "horus/service_message.hpp"
#include "horus/service_registry.hpp"
#include "horus/service_result.hpp"
#include "horus/service_retry.hpp"
#include "horus/service_server.hpp"
#include "horus/service_type.hpp"
