#include "proto/convert.h"

#include "base/limits.h"

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
  for (const auto& a : rep.axes()) m.axes.push_back(Axis{a.name(), std::vector<double>(a.values().begin(), a.values().end())});
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
    return Status::InvalidArgument("lease", "a lease of " + std::to_string(rep.points_size()) + " items violates items <= " +
                                                std::to_string(limits::kMaxLeaseItems));
  if (rep.points_size() != rep.ics_size())
    return Status::InvalidArgument("lease", "a lease with " + std::to_string(rep.points_size()) + " points and " +
                                                std::to_string(rep.ics_size()) + " initial-condition slots");
  std::vector<WorkItem> items(rep.points_size());
  for (int i = 0; i < rep.points_size(); ++i) items[i] = {rep.points(i), rep.ics(i)};
  return items;
}

void ToProto(const std::vector<PointRecord>& records, v1::ReportRequest* req) {
  req->set_record_width(records.empty() ? 0 : static_cast<unsigned>(records[0].v.size()));
  req->set_catalog_hash(CatalogHash());
  for (const auto& r : records) req->mutable_values()->Add(r.v.begin(), r.v.end());
}

}  // namespace bistable
