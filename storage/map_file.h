// One HDF5 file per sweep (<data>/sweeps/<id>.h5), netCDF-4 compatible and CF-1.10 (docs/map-files.md):
// a dataset per metric shaped by the sweep's axes (plus a trailing "ic" or "direction" dimension),
// hd_peak_freq/hd_peak_amp with a trailing "peak" dimension, turning_points with "turning_point",
// fractions of motion types over the initial conditions. Every dimension has a coordinate variable
// (dimension scale); fixed parameters are scalar coordinates; variables carry long_name, UDUNITS units
// (or flag_values/flag_meanings for codes), unit_label (the plots' label) and definition; global
// attributes carry provenance (Conventions, source, history, spec, versions, the writing host's CPU
// and lanes: host_cpu_model, host_simd_isa, host_lane_width; merged_from_shards for a merged map). Chunked, shuffled
// and deflated. Written to a temporary file, fsynced and renamed into place: a reader never sees a partial file.
#ifndef BISTABLE_STORAGE_MAP_FILE_H_
#define BISTABLE_STORAGE_MAP_FILE_H_

#include <string>
#include <vector>

#include "base/status.h"
#include "engine/map_array.h"
#include "engine/metric_catalog.h"
#include "engine/refine.h"
#include "engine/sweep_spec.h"

namespace bistable {

// Where a map's records came from, beyond the spec (provenance attributes).
struct MapOrigin {
  int merged_from_shards = 0;  // > 0: assembled by `bistable merge` from that many shard stores (the root
                               // attribute merged_from_shards, and said in history)
};

// records[point * ic_count + ic], point in the spec's row-major order.
Status WriteMapFile(const std::string& path, const SweepSpec& spec, const std::vector<PointRecord>& records,
                    const MapOrigin& origin = {});
// A refined map ([refine]): the finest grid's records plus refine_level and refine_fill.
Status WriteMapFile(const std::string& path, const SweepSpec& spec, const RefinedGrid& refined);

// The shape an index's map rows give a sweep's metrics: the axis lengths, then the initial conditions
// when there are several ("201x201", "64x64x2").
std::string MapShape(const SweepSpec& spec);

// A metric read back (engine/map_array.h).
StatusOr<MapArray> ReadMapMetric(const std::string& path, const std::string& metric);
// Names of the datasets holding metrics (not the axis scales).
StatusOr<std::vector<std::string>> ListMapMetrics(const std::string& path);
// A root attribute's text ("spec", "numerics_version", "model", "sweep_id", "name", "host_cpu_model", ...);
// a scalar integer one ("host_lane_width") as its decimal digits; "" when absent or of another type.
StatusOr<std::string> ReadMapAttribute(const std::string& path, const std::string& name);

}  // namespace bistable

#endif  // BISTABLE_STORAGE_MAP_FILE_H_
