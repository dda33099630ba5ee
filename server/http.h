// Read-only HTTP endpoint for dashboards: JSON of jobs, a job's samples and results, and
// Prometheus /metrics. Plain HTTP/1.0, one request per connection, GET only.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "executor.h"
#include "store.h"

namespace activefoam::server {

class HttpEndpoint {
 public:
  HttpEndpoint(Store& store, Executor& pool,
               const std::string& listen);  // throws when it cannot bind
  ~HttpEndpoint();
  int port() const { return port_; }

  // The response body and content type for a path (exposed for tests); status in `code`.
  std::string handle(const std::string& path, int& code, std::string& content_type);

 private:
  void loop();
  Store& store_;
  Executor& pool_;
  int fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace activefoam::server
