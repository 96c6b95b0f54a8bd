// The live dashboard: routes for the project's one HTTP server (net/http_server.h) over a sweep
// coordinator — the page and its assets (compiled into the binary from server/dashboard/), and a JSON
// API the page polls: sweeps and workers, a sweep's spec and axes, a map slice (published file, or what
// is stored so far of a running sweep), a query's matching cells, and one cell computed on demand by
// the same code and JSON builder as `bistable point --json` (engine/json_shapes.h). Served by
// `bistable-coordinator --http` and `bistable run --serve`. docs/dashboard.md describes every route.
//
// Auth: with a tokens file, every /api/ route needs a token of role viewer, client or admin (worker
// tokens are refused), given as "Authorization: Bearer <token>" or in the HttpOnly cookie that
// /api/session sets from such a header; the page itself and its assets carry no data and are public.
// Every parameter is bounded and checked: ids through SweepCoordinator::ResolveId, metric and axis names
// against the sweep's, indices against the shape, numbers parsed whole.
#ifndef BISTABLE_SERVER_DASHBOARD_H_
#define BISTABLE_SERVER_DASHBOARD_H_

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "net/http_server.h"
#include "server/auth.h"
#include "server/map_cache.h"
#include "server/sweep_coordinator.h"

namespace bistable {

// The dashboard's routes over `c` (both must outlive the server). `tokens` disabled: open (loopback),
// and every route answers only requests whose Host passes HostAllowed (net/http_server.h: an IP literal,
// localhost or one of `allowed_hosts`), the rule of the --metrics listener too. `maps`: the published maps'
// cache to share with the gRPC service (CoordinatorService); none: one of the routes' own.
std::map<std::string, HttpHandler> DashboardRoutes(SweepCoordinator* c, const TokenStore* tokens,
                                                   std::vector<std::string> allowed_hosts = {},
                                                   std::shared_ptr<MapCache> maps = nullptr);

// The server options DashboardRoutes want: the routes that may take long (a cell integrates a point; a map
// or query reads a map file) are slow routes, so that /healthz and /metrics on the same listener keep
// answering, and cells are heavy routes (HttpServer::Options::heavy_routes: at most one computes at a time,
// taken in turn by client), so that maps and queries always have a thread.
HttpServer::Options DashboardHttpOptions();

// The cookie /api/session sets (HttpOnly, SameSite=Strict, Secure over TLS).
inline constexpr const char* kDashboardCookie = "bistable_token";

}  // namespace bistable

#endif  // BISTABLE_SERVER_DASHBOARD_H_
