// JSON shapes of the CLI (scripts depend on them; see README "JSON output").
#ifndef BISTABLE_CLIENT_JSON_OUT_H_
#define BISTABLE_CLIENT_JSON_OUT_H_

#include <string>

#include <nlohmann/json.hpp>

#include "engine/json_shapes.h"
#include "engine/sweep_state.h"
#include "proto/coordinator_client.h"

namespace bistable {

// A coordinator's answers beyond engine/json_shapes.h's SweepStatusJson and WorkerJson: a row of
// `sweeps --coordinator --json` (RemoteSweepJson), `submit --json` (SubmittedJson).
nlohmann::json RemoteSweepJson(const SweepInfo& s);
nlohmann::json SubmittedJson(const CoordinatorClient::Submitted& s);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_JSON_OUT_H_
