// Files compiled into the binary (cmake/embed_files.cmake): the dashboard's assets (server/dashboard/).
#ifndef BISTABLE_SERVER_EMBEDDED_FILES_H_
#define BISTABLE_SERVER_EMBEDDED_FILES_H_

#include <string_view>
#include <vector>

namespace bistable {

struct EmbeddedFile {
  std::string_view name, content_type, bytes;  // name: the file name in server/dashboard/
};

// index.html, app.js, app.css: generated from server/dashboard/ at build time.
const std::vector<EmbeddedFile>& DashboardAssets();

}  // namespace bistable

#endif  // BISTABLE_SERVER_EMBEDDED_FILES_H_
