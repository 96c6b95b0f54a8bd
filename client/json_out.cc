#include "client/json_out.h"

namespace bistable {

nlohmann::json RemoteSweepJson(const SweepInfo& s) {
  return {{"id", s.id},
          {"name", s.name},
          {"model", s.model},
          {"status", SweepStateName(s.state)},
          {"owner", s.owner},
          {"items_total", s.items_total},
          {"items_done", s.items_done},
          {"items_cached", s.items_cached},
          {"workers", s.workers},
          {"seconds", s.seconds},
          {"file", s.file.empty() ? nlohmann::json(nullptr) : nlohmann::json(s.file)},
          {"error", s.error.empty() ? nlohmann::json(nullptr) : nlohmann::json(s.error)},
          {"created", JsonTime(s.created)},
          {"finished", JsonTime(s.finished)}};
}

nlohmann::json SubmittedJson(const CoordinatorClient::Submitted& s) {
  return {{"id", s.id}, {"items_total", s.items_total}, {"items_cached", s.items_cached}, {"jobs", s.jobs}};
}

}  // namespace bistable
