// The dashboard page (server/dashboard/, and Debian's Chart.js) compiled into foamd: nothing a
// browser loads comes from anywhere but foamd itself.
#pragma once

#include <string>
#include <string_view>

namespace activefoam::server {

struct DashboardAsset {
  const char* path;  // as requested: "/", "/app.js", ...
  const char* content_type;
  std::string_view body;
};

// The asset served at `path`, or nullptr.
const DashboardAsset* findDashboardAsset(const std::string& path);

}  // namespace activefoam::server
