// list_services(): registrations are ordinary topics (`<Service>.service`, type
// horus.ServiceRegistration), found through the transport's own listing.
#include "horus/service_registry.hpp"

#include <optional>

#include "horus/detail/service_channel.hpp"
#include "horus/detail/service_frame.hpp"
#include "horus/topic.hpp"
#include "horus/topic_registry.hpp"
#include "horus/type_info.hpp"

namespace horus {

std::vector<ServiceInfo> list_services(std::string_view namespace_name) {
  const std::vector<TopicInfo> topics = list_topics(namespace_name);
  TopicOptions options;
  options.namespace_name = std::string(namespace_name);
  std::vector<ServiceInfo> services;
  for (const TopicInfo& topic : topics) {
    const std::string_view name = topic.name;
    const std::string_view suffix = kServiceRegistrationSuffix;
    if (topic.type_name != TypeInfo<ServiceRegistration>::name || name.size() <= suffix.size() ||
        name.substr(name.size() - suffix.size()) != suffix) {
      continue;
    }
    ServiceInfo info;
    info.name = std::string(name.substr(0, name.size() - suffix.size()));
    const Topic<ServiceRegistration> handle(topic.name, detail::registration_options(options));
    if (const std::optional<ServiceRegistration> current = handle.read_latest()) {
      info.request_type = current->request_type.str();
      info.response_type = current->response_type.str();
      info.fingerprint = current->fingerprint;
      if (current->server_pid != 0 && !detail::server_process_gone(current->server_pid)) {
        info.servers = 1;
        info.server_pid = static_cast<std::uint32_t>(current->server_pid);
      }
    }
    // Every client receives on a reply topic `<name>.response.<k>` (see detail/service_frame.hpp).
    const std::string replies = info.name + ".response.";
    for (const TopicInfo& reply : topics) {
      if (reply.name.compare(0, replies.size(), replies) == 0) {
        info.clients += reply.subscribers;
      }
    }
    services.push_back(std::move(info));
  }
  return services;
}

}  // namespace horus
