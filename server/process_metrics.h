#pragma once
// The process's own resources on /metrics, under the names Prometheus' client libraries use
// (process_resident_memory_bytes and friends), so that the usual dashboards and alerts work:
// prometheus-cpp has no process collector. Read from /proc at each scrape; on a system without
// /proc the families are left out rather than reported as 0.
#include <prometheus/collectable.h>
#include <prometheus/metric_family.h>

#include <vector>

namespace ism::server {

class ProcessMetrics : public prometheus::Collectable {
 public:
  std::vector<prometheus::MetricFamily> Collect() const override;
};

}  // namespace ism::server
