#include "proto/convert.h"

#include <algorithm>

#include "base/limits.h"
#include "base/sha256.h"

namespace bistable {

void ToProto(const SweepInfo& i, v1::SweepStatus* s) {
  s->set_id(i.id);
  s->set_state(SweepStateName(i.state));
  s->set_items_done(i.items_done);
  s->set_items_total(i.items_total);
  s->set_items_cached(i.items_cached);
  s->set_workers(i.workers);
  s->set_seconds(i.seconds);
  s->set_file(i.file);
  s->set_name(i.name);
  s->set_model(i.model);
  s->set_error(i.error);
  s->set_owner(i.owner);
  s->set_created(i.created);
  s->set_finished(i.finished);
}

SweepInfo FromProto(const v1::SweepStatus& s) {
  SweepInfo i;
  i.id = s.id();
  i.state = ParseSweepState(s.state()).value_or(SweepState::kFailed);
  i.items_done = s.items_done();
  i.items_total = s.items_total();
  i.items_cached = s.items_cached();
  i.workers = s.workers();
  i.seconds = s.seconds();
  i.file = s.file();
  i.name = s.name();
  i.model = s.model();
  i.error = s.error();
  i.owner = s.owner();
  i.created = s.created();
  i.finished = s.finished();
  return i;
}

void ToProto(const WorkerInfo& w, v1::WorkerStatus* s) {
  s->set_name(w.name);
  s->set_last_seen(w.last_seen);
  s->set_leases(w.leases);
  s->set_items_done(w.items_done);
}

WorkerInfo FromProto(const v1::WorkerStatus& s) { return {s.name(), s.last_seen(), s.leases(), s.items_done()}; }

void ToProto(const MapArray& m, v1::MapReply* rep) {
  rep->set_metric(m.metric);
  rep->set_unit(m.unit);
  rep->set_definition(m.definition);
  for (const Axis& a : m.axes) {
    v1::Axis* ax = rep->add_axes();
    ax->set_name(a.name);
    ax->set_unit(AxisUnit(a.name));
    ax->mutable_values()->Add(a.values.begin(), a.values.end());
  }
  for (size_t d : m.dims) rep->add_dims(d);
  for (const auto& n : m.dim_names) rep->add_dim_names(n);
  rep->mutable_values()->Add(m.values.begin(), m.values.end());
}

MapArray FromProto(const v1::MapReply& rep) {
  MapArray m;
  m.metric = rep.metric();
  m.unit = rep.unit();
  m.definition = rep.definition();
  for (const auto& a : rep.axes())
    m.axes.push_back(Axis{a.name(), std::vector<double>(a.values().begin(), a.values().end())});
  for (auto d : rep.dims()) m.dims.push_back(d);
  m.dim_names.assign(rep.dim_names().begin(), rep.dim_names().end());
  m.values.assign(rep.values().begin(), rep.values().end());
  return m;
}

void ToProto(const std::vector<WorkItem>& items, v1::LeaseReply* rep) {
  for (const WorkItem& w : items) rep->add_points(w.point), rep->add_ics(w.ic);
}

StatusOr<std::vector<WorkItem>> ItemsFromProto(const v1::LeaseReply& rep) {
  if (rep.points_size() > limits::kMaxLeaseItems)  // before anything is allocated for them
    return Status::InvalidArgument("lease", "a lease of " + std::to_string(rep.points_size()) +
                                                " items violates items <= " + std::to_string(limits::kMaxLeaseItems));
  if (rep.points_size() != rep.ics_size())
    return Status::InvalidArgument("lease", "a lease with " + std::to_string(rep.points_size()) + " points and " +
                                                std::to_string(rep.ics_size()) + " initial-condition slots");
  std::vector<WorkItem> items(rep.points_size());
  for (int i = 0; i < rep.points_size(); ++i) items[i] = {rep.points(i), rep.ics(i)};
  return items;
}

void ToProto(const SubmitResult& in, v1::SubmitReply* out) {
  out->set_id(in.id);
  out->set_items_total(in.items_total);
  out->set_items_cached(in.items_cached);
  out->set_jobs(in.jobs);
}

SubmitResult FromProto(const v1::SubmitReply& in) { return {in.id(), in.items_total(), in.items_cached(), in.jobs()}; }

void ToProto(const MetricList& in, v1::MetricsReply* out) {
  out->set_id(in.id);
  out->set_name(in.name);
  for (const auto& m : in.metrics) out->add_metrics(m);
}

MetricList FromProto(const v1::MetricsReply& in) {
  return {in.id(), in.name(), std::vector<std::string>(in.metrics().begin(), in.metrics().end())};
}

std::string SpecKey(std::string_view spec_toml) { return Sha256Hex(spec_toml); }

bool IsSpecKey(std::string_view key) {
  return key.size() == 64 && key.find_first_not_of("0123456789abcdef") == std::string_view::npos;
}

StatusOr<std::vector<std::string>> KnownSpecsFromProto(const google::protobuf::RepeatedPtrField<std::string>& in,
                                                       const std::string& field) {
  if (in.size() > limits::kMaxKnownSpecs)  // before anything is copied
    return Status::InvalidArgument(field, field + " names " + std::to_string(in.size()) +
                                              " spec keys, over the limit of " +
                                              std::to_string(limits::kMaxKnownSpecs));
  std::vector<std::string> keys;
  for (int i = 0; i < in.size(); ++i) {
    if (!IsSpecKey(in.Get(i)))
      return Status::InvalidArgument(field,
                                     field + "[" + std::to_string(i) + "] is not a spec key (64 lowercase hex digits)");
    keys.push_back(in.Get(i));
  }
  return keys;
}

namespace {

bool IsSweepId(std::string_view id) {
  return !id.empty() && id.size() <= limits::kMaxIdBytes &&
         id.find_first_not_of("0123456789abcdef") == std::string_view::npos;
}

}  // namespace

void ToProto(const LeasedWork& in, v1::LeaseReply* out) {
  out->set_has_job(true);
  out->set_lease_id(in.lease_id);
  out->set_sweep_id(in.sweep_id);
  out->set_job_id(in.job_id);
  out->set_spec_toml(in.spec_toml);
  out->set_spec_key(in.spec_key);
  ToProto(in.items, out);
  out->set_deadline(in.deadline);
}

StatusOr<std::optional<LeasedWork>> FromProto(const v1::LeaseReply& in) {
  if (!in.has_job()) return std::optional<LeasedWork>();
  // Ids go into requests, log lines and the spec cache: bounded and plain, as the coordinator makes them.
  if (in.lease_id().empty() || in.lease_id().size() > limits::kMaxIdBytes ||
      std::any_of(in.lease_id().begin(), in.lease_id().end(), [](char c) { return c < 0x21 || c > 0x7e; }))
    return Status::InvalidArgument(
        "lease", "lease_id violates 1 to " + std::to_string(limits::kMaxIdBytes) + " visible ASCII characters");
  if (!IsSweepId(in.sweep_id()))
    return Status::InvalidArgument(
        "lease", "sweep_id violates 1 to " + std::to_string(limits::kMaxIdBytes) + " lowercase hex digits");
  if (!in.spec_key().empty() && !IsSpecKey(in.spec_key()))
    return Status::InvalidArgument("lease", "spec_key is not a spec key (64 lowercase hex digits)");
  if (in.spec_toml().size() > limits::kMaxSpecBytes)
    return Status::InvalidArgument("lease", "spec_toml is " + std::to_string(in.spec_toml().size()) +
                                                " bytes, over the limit of " + std::to_string(limits::kMaxSpecBytes));
  auto items = ItemsFromProto(in);
  if (!items.ok()) return items.status();
  return std::optional<LeasedWork>(LeasedWork{in.lease_id(), in.sweep_id(), static_cast<long>(in.job_id()),
                                              in.spec_toml(), in.spec_key(), std::move(*items), in.deadline()});
}

void ToProto(const SpecText& in, v1::SpecReply* out) {
  out->set_sweep_id(in.sweep_id);
  out->set_spec_toml(in.spec_toml);
  out->set_spec_key(in.spec_key);
}

StatusOr<SpecText> FromProto(const v1::SpecReply& in) {
  if (!IsSweepId(in.sweep_id()))
    return Status::InvalidArgument(
        "spec", "sweep_id violates 1 to " + std::to_string(limits::kMaxIdBytes) + " lowercase hex digits");
  if (in.spec_toml().size() > limits::kMaxSpecBytes)
    return Status::InvalidArgument("spec", "spec_toml is " + std::to_string(in.spec_toml().size()) +
                                               " bytes, over the limit of " + std::to_string(limits::kMaxSpecBytes));
  if (in.spec_key() != SpecKey(in.spec_toml()))
    return Status::InvalidArgument("spec", "spec_key is not the SHA-256 of spec_toml");
  return SpecText{in.sweep_id(), in.spec_toml(), in.spec_key()};
}

void ToProto(const MapChunk& in, v1::FileChunk* out) {
  out->set_id(std::string(in.id));
  out->set_offset(in.offset);
  out->set_total_bytes(in.total_bytes);
  out->set_data(in.data.data(), in.data.size());
  if (!in.sha256.empty()) out->set_sha256(std::string(in.sha256));
}

void ToProto(const std::vector<PointRecord>& records, v1::ReportRequest* req) {
  req->set_record_width(records.empty() ? 0 : static_cast<unsigned>(records[0].v.size()));
  req->set_catalog_hash(CatalogHash());
  for (const auto& r : records) req->mutable_values()->Add(r.v.begin(), r.v.end());
}

}  // namespace bistable
