// Prometheus text exposition of collectables (prometheus-cpp's registry and families), as an HTTP
// response for HttpServer's "/metrics" route.
#ifndef BISTABLE_NET_PROMETHEUS_TEXT_H_
#define BISTABLE_NET_PROMETHEUS_TEXT_H_

#include <memory>
#include <vector>

#include <prometheus/collectable.h>

#include "net/http_server.h"

namespace bistable {

HttpResponse PrometheusText(const std::vector<std::shared_ptr<prometheus::Collectable>>& sources);

}  // namespace bistable

#endif  // BISTABLE_NET_PROMETHEUS_TEXT_H_
