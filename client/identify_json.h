// The JSON of a fit as `bistable identify --json` prints it and the Python module returns it: the result, the
// fitted parameters, and the errors over one and four drive periods (also --predict's). Scripts depend on these
// shapes (docs/identification.md, "What the JSON says").
#ifndef BISTABLE_CLIENT_IDENTIFY_JSON_H_
#define BISTABLE_CLIENT_IDENTIFY_JSON_H_

#include <vector>

#include <nlohmann/json.hpp>

#include "identify/identify.h"

namespace bistable {

// {name: value} of every parameter of m at the fit's θ.
nlohmann::json ParamsJson(const IdentModel& m, const FitResult& f);
// A model under a JSON key (e.g. "before", "after").
struct KeyedModel {
  const char* key;
  const IdentModel* m;
  const std::vector<double>* th;
};
// The errors of a record over one and four drive periods (DriveFrequency) from the measured state, one key per
// model: [{drive_periods, horizon_s, <key>: NRMSE %}].
nlohmann::json DrivePeriodErrors(const PreparedRecord& r, const Setup& setup, const std::vector<KeyedModel>& models);
// The whole JSON of a fit.
nlohmann::json ResultJson(const identify::Options& o, const identify::Summary& s);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_IDENTIFY_JSON_H_
