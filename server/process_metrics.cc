#include "server/process_metrics.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>

namespace ism::server {
namespace {

prometheus::MetricFamily family(const char* name, const char* help, prometheus::MetricType type, double value) {
  prometheus::MetricFamily out{name, help, type, {}};
  prometheus::ClientMetric metric;
  if (type == prometheus::MetricType::Counter) {
    metric.counter.value = value;
  } else {
    metric.gauge.value = value;
  }
  out.metric.push_back(metric);
  return out;
}

}  // namespace

std::vector<prometheus::MetricFamily> ProcessMetrics::Collect() const {
  std::vector<prometheus::MetricFamily> families;
  const double page = static_cast<double>(sysconf(_SC_PAGESIZE));
  // statm: sizes in pages, the first two the virtual and the resident size.
  std::ifstream statm("/proc/self/statm");
  double virtual_pages = 0, resident_pages = 0;
  if (statm >> virtual_pages >> resident_pages) {
    families.push_back(family("process_resident_memory_bytes", "Resident memory size in bytes.",
                              prometheus::MetricType::Gauge, resident_pages * page));
    families.push_back(family("process_virtual_memory_bytes", "Virtual memory size in bytes.",
                              prometheus::MetricType::Gauge, virtual_pages * page));
  }
  // stat: utime and stime are fields 14 and 15, in clock ticks. The command name (field 2) may
  // hold blanks, so counting starts after its closing parenthesis.
  std::ifstream stat_file("/proc/self/stat");
  const std::string stat{std::istreambuf_iterator<char>(stat_file), std::istreambuf_iterator<char>()};
  const size_t name_end = stat.rfind(')');
  if (name_end != std::string::npos) {
    std::istringstream fields(stat.substr(name_end + 2));
    std::string field;
    double utime = -1, stime = -1;
    for (int n = 3; n <= 15 && fields >> field; ++n) {
      if (n == 14) utime = std::stod(field);
      if (n == 15) stime = std::stod(field);
    }
    if (utime >= 0 && stime >= 0) {
      families.push_back(family("process_cpu_seconds_total", "Total user and system CPU time spent in seconds.",
                                prometheus::MetricType::Counter,
                                (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK))));
    }
  }
  std::error_code ec;
  size_t fds = 0;
  for (std::filesystem::directory_iterator it("/proc/self/fd", ec), end; !ec && it != end; it.increment(ec)) ++fds;
  if (!ec) {
    families.push_back(family("process_open_fds", "Number of open file descriptors.", prometheus::MetricType::Gauge,
                              static_cast<double>(fds)));
  }
  return families;
}

}  // namespace ism::server
