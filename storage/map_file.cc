#include "storage/map_file.h"

#include <atomic>

#include <fcntl.h>
#include <hdf5.h>
#include <hdf5_hl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>

#include "base/iso_time.h"
#include "base/limits.h"
#include "base/names.h"
#include "base/validate.h"
#include "base/version.h"
#include "dynamics/host_lanes.h"
#include "engine/sweep_kind.h"
#include "storage/data_dir.h"
#include "storage/metric_name.h"

namespace bistable {
namespace {

// RAII for hid_t handles.
class Handle {
 public:
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  ~Handle() {
    if (id_ >= 0) close_(id_);
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  hid_t get() const { return id_; }
  bool ok() const { return id_ >= 0; }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

// Every HDF5 call of the process is in this file, under this one lock: the dashboard reads maps on two threads
// beside the publisher thread's writing, HDF5's high-level dimension-scale API (H5DS, used here) is not
// thread-safe even in thread-safe builds, and default builds of the library are not thread-safe at all.
std::recursive_mutex& Hdf5Mutex() {
  static std::recursive_mutex mu;
  return mu;
}

Status H5Fail(const std::string& path, const std::string& what) {
  return Status::IoError("map", "HDF5 " + what + " failed for '" + path + "'");
}

// Variable-length UTF-8 strings: h5py reads them as str.
hid_t Utf8Type() {
  const hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_size(t, H5T_VARIABLE);
  H5Tset_cset(t, H5T_CSET_UTF8);
  return t;
}

Status WriteStringAttr(hid_t obj, const char* name, const std::string& value) {
  Handle type(Utf8Type(), H5Tclose);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle attr(H5Acreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  const char* p = value.c_str();
  if (!attr.ok() || H5Awrite(attr.get(), type.get(), &p) < 0)
    return Status::IoError("map", std::string("attribute ") + name);
  return Status::Ok();
}

std::string ReadStringAttr(hid_t obj, const char* name) {
  if (H5Aexists(obj, name) <= 0) return "";
  Handle attr(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose);
  Handle type(H5Aget_type(attr.get()), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING || H5Tis_variable_str(type.get()) <= 0) return "";
  Handle mem(Utf8Type(), H5Tclose);
  char* p = nullptr;
  if (H5Aread(attr.get(), mem.get(), &p) < 0 || !p) return "";
  std::string s(p);
  H5free_memory(p);
  return s;
}

Status WriteNumberAttr(hid_t obj, const char* name, hid_t type, const void* values, size_t n) {
  const hsize_t dims = n;
  Handle space(n == 1 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &dims, nullptr), H5Sclose);
  Handle attr(H5Acreate2(obj, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!attr.ok() || H5Awrite(attr.get(), type, values) < 0)
    return Status::IoError("map", std::string("attribute ") + name);
  return Status::Ok();
}

// How a quantity is described in the file (CF-1.10): units, a long name, and the label the plots use
// (unit_label, e.g. "1/tau", "A0/delta_s"). units are UDUNITS-parsable, or "dB" (the unit of the CF
// standard-name table's levels; not UDUNITS'). A quantity scaled by the model's references (1/tau,
// delta_s, A0/delta_s, ...) is dimensionless: it has no units (CF 3.1: none means dimensionless; "1"
// made xarray label its plots "[1]") and its scale in `unit`, which xarray shows when there are no units,
// and in the comment. Code metrics carry flag_values/flag_meanings instead of units. No CF standard name
// describes these quantities, so none is written.
struct CfQuantity {
  std::string long_name, label, definition;
  const std::vector<Category>* categories = nullptr;
};

struct CfUnits {
  std::string units, comment;
};

CfUnits CfUnitsFor(const std::string& label) {
  static const std::map<std::string, CfUnits> kUnits = {
      {"dB", {"dB", "decibels: 20 log10 of an amplitude ratio"}},
      {"%", {"percent", ""}},
      {"fraction", {"1", ""}},
      {"", {"1", ""}},
      {"forcing periods", {"", "counted in forcing periods 2 pi/Omega"}},
      {"1/tau", {"", "per unit of non-dimensional time tau = omega_n t"}},
      {"tau", {"", "non-dimensional time tau = omega_n t"}},
      {"rad/tau", {"", "angular frequency in units of omega_n (rad per unit of tau)"}},
      {"delta_s", {"", "in units of delta_s, the static position of a well"}},
      {"delta_s/tau", {"", "velocity in units of delta_s omega_n (delta_s per unit of non-dimensional time tau)"}},
      {"1/s", {"s-1", ""}},
      {"rad/s", {"rad/s", ""}},
      {"m", {"m", ""}},
      {"mm", {"mm", ""}},
      {"Hz", {"Hz", ""}},
      {"kg", {"kg", ""}},
      {"N", {"N", ""}},
      {"N/m", {"N/m", ""}},
      {"N/m^3", {"N/m3", ""}},
      {"N s/m", {"N s/m", ""}},
      {"N s/m^3", {"N s/m3", ""}},
      {"m/s", {"m/s", ""}}};
  auto it = kUnits.find(label);
  if (it != kUnits.end()) return it->second;
  return {"", "non-dimensional: " + label};  // the paper's ratios (A0/delta_s, omega_r/omega_n, ...)
}

Status WriteCfAttrs(hid_t obj, const CfQuantity& q, const std::string& coordinates) {
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "long_name", q.long_name));
  if (q.categories) {
    std::vector<int32_t> values;
    std::string meanings;
    for (const Category& c : *q.categories) {
      values.push_back(c.code);
      if (!meanings.empty()) meanings += ' ';
      meanings += c.name;
    }
    BISTABLE_RETURN_IF_ERROR(WriteNumberAttr(obj, "flag_values", H5T_NATIVE_INT32, values.data(), values.size()));
    BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "flag_meanings", meanings));
  } else {
    const CfUnits u = CfUnitsFor(q.label);
    if (u.units.empty()) {
      BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "unit", q.label));
    } else {
      BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "units", u.units));
    }
    if (!u.comment.empty()) BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "comment", u.comment));
  }
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "unit_label", q.label));
  if (!q.definition.empty()) BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "definition", q.definition));
  if (!coordinates.empty()) BISTABLE_RETURN_IF_ERROR(WriteStringAttr(obj, "coordinates", coordinates));
  return Status::Ok();
}

// Creates a chunked, shuffled, deflated dataset and writes `data` (converted to `file_type`).
Status WriteDataset(hid_t file, const std::string& name, const std::vector<hsize_t>& dims,
                    const std::vector<double>& data, hid_t file_type, const CfQuantity& q,
                    const std::string& coordinates) {
  Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  // Chunks of about 8,192 values (64 KiB of doubles): whole trailing dims, then as many rows of the
  // leading ones as fit. (Chunks of 128 values cost more in per-chunk filter and B-tree work than in
  // compression: a 201 × 201 map had 402 chunks per dataset.)
  std::vector<hsize_t> chunk(dims.size(), 1);
  hsize_t fill = 1;
  for (size_t k = dims.size(); k-- > 0;) {
    const hsize_t room = std::max<hsize_t>(1, 8192 / fill);
    chunk[k] = std::max<hsize_t>(1, std::min(dims[k], room));
    fill *= chunk[k];
  }
  H5Pset_chunk(dcpl.get(), static_cast<int>(dims.size()), chunk.data());
  H5Pset_shuffle(dcpl.get());
  H5Pset_deflate(dcpl.get(), 4);
  if (file_type == H5T_NATIVE_DOUBLE) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    H5Pset_fill_value(dcpl.get(), H5T_NATIVE_DOUBLE, &nan);
  }
  Handle ds(H5Dcreate2(file, name.c_str(), file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT), H5Dclose);
  if (!ds.ok()) return Status::IoError("map", "create dataset " + name);
  herr_t rc;
  if (file_type == H5T_NATIVE_DOUBLE) {
    rc = H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data());
  } else {
    std::vector<int32_t> ints(data.size());
    for (size_t i = 0; i < data.size(); ++i) ints[i] = std::isfinite(data[i]) ? static_cast<int32_t>(data[i]) : -1;
    rc = H5Dwrite(ds.get(), H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, ints.data());
  }
  if (rc < 0) return Status::IoError("map", "write dataset " + name);
  return WriteCfAttrs(ds.get(), q, coordinates);
}

Status AttachScales(hid_t file, const std::string& name, const std::vector<std::string>& dim_names) {
  Handle ds(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
  for (size_t k = 0; k < dim_names.size(); ++k) {
    Handle scale(H5Dopen2(file, dim_names[k].c_str(), H5P_DEFAULT), H5Dclose);
    if (!scale.ok() || H5DSattach_scale(ds.get(), scale.get(), static_cast<unsigned>(k)) < 0)
      return Status::IoError("map", "attach scale " + dim_names[k] + " to " + name);
    H5DSset_label(ds.get(), static_cast<unsigned>(k), dim_names[k].c_str());
  }
  return Status::Ok();
}

// A coordinate variable: a 1-D dimension scale named like its dimension. Index coordinates (ic,
// direction, peak, turning_point) are 32-bit integers, so a flag_values attribute has their type (CF §3.5).
Status WriteScale(hid_t file, const std::string& name, const std::vector<double>& values, const CfQuantity& q,
                  bool integer = false) {
  const std::vector<hsize_t> dims = {values.size()};
  Handle space(H5Screate_simple(1, dims.data(), nullptr), H5Sclose);
  const hid_t type = integer ? H5T_NATIVE_INT32 : H5T_NATIVE_DOUBLE;
  Handle ds(H5Dcreate2(file, name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
  herr_t rc = -1;
  if (ds.ok() && integer) {
    std::vector<int32_t> ints(values.begin(), values.end());
    rc = H5Dwrite(ds.get(), H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, ints.data());
  } else if (ds.ok()) {
    rc = H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
  }
  if (rc < 0) return Status::IoError("map", "write axis " + name);
  if (H5DSset_scale(ds.get(), name.c_str()) < 0) return Status::IoError("map", "set scale " + name);
  return WriteCfAttrs(ds.get(), q, "");
}

// A fixed parameter: a scalar variable that the data variables name in their "coordinates".
Status WriteScalar(hid_t file, const std::string& name, double value, const CfQuantity& q) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle ds(H5Dcreate2(file, name.c_str(), H5T_NATIVE_DOUBLE, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
            H5Dclose);
  if (!ds.ok() || H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) < 0)
    return Status::IoError("map", "write parameter " + name);
  return WriteCfAttrs(ds.get(), q, "");
}

Status FsyncPath(const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) return Status::IoError("map", "open for fsync: " + path);
  const int rc = ::fsync(fd);
  ::close(fd);
  return rc == 0 ? Status::Ok() : Status::IoError("map", "fsync " + path);
}

// Dimensional sweeps measure in SI: time in s, lengths in m, angular frequencies in rad/s.
std::string UnitFor(const SweepSpec& spec, std::string unit) {
  if (spec.model != ModelKind::kDimensional) return unit;
  for (auto [from, to] : {std::pair<std::string, std::string>{"rad/tau", "rad/s"},
                          {"1/tau", "1/s"},
                          {"delta_s", "m"},
                          {"delta_s/tau", "m/s"}})
    if (unit == from) return to;
  return unit;
}

std::vector<double> Iota(size_t n) {
  std::vector<double> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = static_cast<double>(i);
  return v;
}

// What the sweep's kind adds to the map (engine/sweep_kind.h: motion fractions, basins, refinement), in
// the order the kind gives it. Units are the catalog's, in SI for the rig (UnitFor).
Status WriteKindPart(hid_t file, const SweepSpec& spec, const KindMapPart& part, const std::vector<hsize_t>& axis_dims,
                     const std::vector<std::string>& axis_names, const std::vector<hsize_t>& dims,
                     const std::vector<std::string>& names, const std::string& coordinates) {
  // Flag names as CF categories (the strings stay owned by the part while they are written).
  auto categories = [](const std::vector<std::pair<int, std::string>>& labels) {
    std::vector<Category> cats;
    for (const auto& [code, name] : labels) cats.push_back({code, name.c_str()});
    return cats;
  };
  auto write = [&](hid_t where, const KindVariable& v, const std::vector<hsize_t>& d, const std::vector<std::string>& n,
                   const std::string& coords) -> Status {
    const std::vector<Category> cats = categories(v.labels);
    const CfQuantity q{v.long_name, UnitFor(spec, v.unit), v.definition, cats.empty() ? nullptr : &cats};
    BISTABLE_RETURN_IF_ERROR(
        WriteDataset(where, v.name, d, v.values, v.integer ? H5T_NATIVE_INT32 : H5T_NATIVE_DOUBLE, q, coords));
    return AttachScales(where, v.name, n);
  };
  for (const KindVariable& v : part.variables) {
    const bool items = v.over == KindVariable::Over::kItems;
    BISTABLE_RETURN_IF_ERROR(write(file, v, items ? dims : axis_dims, items ? names : axis_names, coordinates));
  }
  if (part.table) {
    const KindMapPart::Table& t = *part.table;
    Handle group(H5Gcreate2(file, t.group.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
    if (!group.ok()) return Status::IoError("map", "create group " + t.group);
    const std::vector<Category> legend = categories(t.labels);
    BISTABLE_RETURN_IF_ERROR(WriteScale(group.get(), t.dimension, Iota(static_cast<size_t>(t.size)),
                                        {t.long_name, "", "", &legend}, /*integer=*/true));
    for (const KindVariable& v : part.table_variables)
      BISTABLE_RETURN_IF_ERROR(write(group.get(), v, {static_cast<hsize_t>(t.size)}, {t.dimension}, ""));
  }
  for (const KindAttribute& a : part.attributes) {
    switch (a.type) {
      case KindAttribute::Type::kDouble:
        BISTABLE_RETURN_IF_ERROR(WriteNumberAttr(file, a.name.c_str(), H5T_NATIVE_DOUBLE, &a.number, 1));
        break;
      case KindAttribute::Type::kLong:
        BISTABLE_RETURN_IF_ERROR(WriteNumberAttr(file, a.name.c_str(), H5T_NATIVE_LONG, &a.integer, 1));
        break;
      case KindAttribute::Type::kString:
        BISTABLE_RETURN_IF_ERROR(WriteStringAttr(file, a.name.c_str(), a.text));
        break;
    }
  }
  return Status::Ok();
}

// The shape every variable of a map is laid out over: the axes (their dimensions, names and the
// "axes" attribute), the fixed parameters as scalar coordinates, and the items' dimensions and names
// (the axes, then the kind's slot dimension when there is more than one slot).
struct MapLayout {
  std::vector<hsize_t> axis_dims;
  std::vector<std::string> axis_names;
  std::string axes_attr;
  std::string coordinates;
  std::vector<hsize_t> dims;
  std::vector<std::string> names;
};

// The axes' scales, the fixed parameters' scalars and the slot dimension's scale, and the layout they give.
Status WriteAxesAndFixed(hid_t file, const SweepSpec& spec, const SweepKind& kind, MapLayout* layout) {
  const int nic = spec.ic_count();
  for (const Axis& a : spec.axes) {
    layout->axis_dims.push_back(a.values.size());
    layout->axis_names.push_back(a.name);
    layout->axes_attr += (layout->axes_attr.empty() ? "" : ",") + a.name;
    BISTABLE_RETURN_IF_ERROR(WriteScale(file, a.name, a.values, {AxisLongName(a.name), AxisUnit(a.name), ""}));
  }
  // Fixed parameters: scalar coordinates of every data variable.
  for (const FixedParameter& p : spec.FixedParameters()) {
    BISTABLE_RETURN_IF_ERROR(WriteScalar(file, p.name, p.value, {p.long_name, p.unit, ""}));
    layout->coordinates += (layout->coordinates.empty() ? "" : " ") + p.name;
  }
  // The trailing item dimension: the kind's slots (initial conditions, continuation directions, samples).
  const SlotDimension slot = kind.Dimension(spec);
  const std::string& item_dim = slot.name;
  if (nic > 1) {
    std::vector<Category> slot_names;
    for (const auto& [code, name] : slot.labels) slot_names.push_back({code, name.c_str()});
    const CfQuantity q{slot.long_name, "", "", slot_names.empty() ? nullptr : &slot_names};
    BISTABLE_RETURN_IF_ERROR(WriteScale(file, item_dim, Iota(nic), q, /*integer=*/true));
  }
  layout->dims = layout->axis_dims;
  layout->names = layout->axis_names;
  if (nic > 1) layout->dims.push_back(nic), layout->names.push_back(item_dim);
  return Status::Ok();
}

// One variable per metric of the spec, in the catalog's order, over the items.
Status WriteMetricVariables(hid_t file, const SweepSpec& spec, const std::vector<PointRecord>& records,
                            const MapLayout& layout) {
  const auto& catalog = MetricCatalog();
  for (size_t mi = 0; mi < catalog.size(); ++mi) {
    const MetricInfo& m = catalog[mi];
    if (std::find(spec.metrics.begin(), spec.metrics.end(), m.name) == spec.metrics.end()) continue;
    std::vector<double> data(records.size());
    for (size_t i = 0; i < records.size(); ++i) data[i] = records[i].Get(mi);
    const std::vector<Category>& cats = MetricCategories(m.name);
    const CfQuantity q{m.long_name, UnitFor(spec, m.unit), m.definition, cats.empty() ? nullptr : &cats};
    BISTABLE_RETURN_IF_ERROR(WriteDataset(file, m.name, layout.dims, data,
                                          m.integer ? H5T_NATIVE_INT32 : H5T_NATIVE_DOUBLE, q, layout.coordinates));
    BISTABLE_RETURN_IF_ERROR(AttachScales(file, m.name, layout.names));
  }
  return Status::Ok();
}

// hd_peaks: the spectral peaks' frequencies and amplitudes over the items and a trailing "peak" rank.
Status WriteHdPeaks(hid_t file, const SweepSpec& spec, const std::vector<PointRecord>& records,
                    const MapLayout& layout) {
  BISTABLE_RETURN_IF_ERROR(WriteScale(file, "peak", Iota(kHdPeaksStored),
                                      {"rank of the spectral peak (0 = strongest)", "", ""}, /*integer=*/true));
  std::vector<hsize_t> pd = layout.dims;
  pd.push_back(kHdPeaksStored);
  std::vector<std::string> pn = layout.names;
  pn.push_back("peak");
  std::vector<double> f(records.size() * kHdPeaksStored), a(f.size());
  for (size_t i = 0; i < records.size(); ++i)
    for (int k = 0; k < kHdPeaksStored; ++k)
      f[i * kHdPeaksStored + k] = records[i].PeakFreq(k), a[i * kHdPeaksStored + k] = records[i].PeakAmp(k);
  BISTABLE_RETURN_IF_ERROR(WriteDataset(file, "hd_peak_freq", pd, f, H5T_NATIVE_DOUBLE,
                                        {"angular frequency of a spectral peak of y_m", UnitFor(spec, "rad/tau"),
                                         "spectral peaks of y_m (strongest first), angular frequency; NaN = none"},
                                        layout.coordinates));
  BISTABLE_RETURN_IF_ERROR(AttachScales(file, "hd_peak_freq", pn));
  BISTABLE_RETURN_IF_ERROR(WriteDataset(file, "hd_peak_amp", pd, a, H5T_NATIVE_DOUBLE,
                                        {"amplitude of y_m at a spectral peak", UnitFor(spec, "delta_s"),
                                         "amplitude of y_m at each spectral peak; NaN = none"},
                                        layout.coordinates));
  return AttachScales(file, "hd_peak_amp", pn);
}

// turning_points: y_m at the window's last turning points over the items and a trailing index.
Status WriteTurningPoints(hid_t file, const SweepSpec& spec, const std::vector<PointRecord>& records,
                          const MapLayout& layout) {
  BISTABLE_RETURN_IF_ERROR(
      WriteScale(file, "turning_point", Iota(kTurningPointsStored),
                 {"index of the turning point (time order within the last 64 of the window)", "", ""},
                 /*integer=*/true));
  std::vector<hsize_t> td = layout.dims;
  td.push_back(kTurningPointsStored);
  std::vector<std::string> tn = layout.names;
  tn.push_back("turning_point");
  std::vector<double> tp(records.size() * kTurningPointsStored);
  for (size_t i = 0; i < records.size(); ++i)
    for (int k = 0; k < kTurningPointsStored; ++k) tp[i * kTurningPointsStored + k] = records[i].TurningPoint(k);
  BISTABLE_RETURN_IF_ERROR(
      WriteDataset(file, "turning_points", td, tp, H5T_NATIVE_DOUBLE,
                   {"displacement y_m at a turning point (y_m' = 0)", UnitFor(spec, "delta_s"),
                    "y_m where y_m' = 0 in the window (last 64, time order; NaN = none): bifurcation diagrams"},
                   layout.coordinates));
  return AttachScales(file, "turning_points", tn);
}

// The Poincare (stroboscopic) section: y_m and y_m' at the last np_section strobes over the items
// and a trailing index.
Status WritePoincareSection(hid_t file, const SweepSpec& spec, const std::vector<PointRecord>& records,
                            const MapLayout& layout, int np_section) {
  const bool tp = spec.base.metrics.turning_points;
  BISTABLE_RETURN_IF_ERROR(WriteScale(file, "poincare_point", Iota(np_section),
                                      {"index of the Poincare section point (time order within the last " +
                                           std::to_string(np_section) + " of the window)",
                                       "", ""},
                                      /*integer=*/true));
  std::vector<hsize_t> sd = layout.dims;
  sd.push_back(np_section);
  std::vector<std::string> sn = layout.names;
  sn.push_back("poincare_point");
  const char* phase_note =
      spec.model == ModelKind::kDimensional ? "t_k = (phase + 2 pi k)/omega_0" : "tau_k = (phase + 2 pi k)/Omega";
  const std::string when = std::string(" at the strobes ") + phase_note +
                           ", phase = poincare_phase = " + FormatNumber(spec.base.metrics.poincare_phase) +
                           " rad, the last " + std::to_string(np_section) + " in the window (time order; NaN = none)";
  const struct {
    const char* name;
    int component;
    const char* long_name;
    const char* unit;
    const char* what;
  } kSection[] = {{"poincare_y", 0, "displacement y_m on the Poincare (stroboscopic) section", "delta_s", "y_m"},
                  {"poincare_v", 1, "velocity y_m' on the Poincare (stroboscopic) section", "delta_s/tau", "y_m'"}};
  for (const auto& c : kSection) {
    std::vector<double> values(records.size() * np_section);
    for (size_t i = 0; i < records.size(); ++i)
      for (int k = 0; k < np_section; ++k)
        values[i * np_section + k] = records[i].Poincare(k, c.component, tp, np_section);
    BISTABLE_RETURN_IF_ERROR(WriteDataset(file, c.name, sd, values, H5T_NATIVE_DOUBLE,
                                          {c.long_name, UnitFor(spec, c.unit), std::string(c.what) + when},
                                          layout.coordinates));
    BISTABLE_RETURN_IF_ERROR(AttachScales(file, c.name, sn));
  }
  return Status::Ok();
}

// The global attributes: CF-1.10's (provenance), then the project's own, then where it was written.
Status WriteProvenanceAttributes(hid_t f, const SweepSpec& spec, const MapOrigin& origin,
                                 const std::string& axes_attr) {
  const IntegrationSettings& in = spec.base.integration;
  const bool dimensional = spec.model == ModelKind::kDimensional;
  char settings[256];
  std::snprintf(settings, sizeof settings, "%s, dt = %.6g, window %.6g to %.6g %s", IntegratorName(in.integrator),
                in.dt, in.t_keep, in.t_end, dimensional ? "s" : "(tau = omega_n t)");
  // CF-1.10 global attributes (provenance), then the project's own.
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "Conventions", "CF-1.10"));
  BISTABLE_RETURN_IF_ERROR(
      WriteStringAttr(f, "title", spec.name.empty() ? "bistable-sweep map " + spec.Id() : spec.name));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "source",
                                           std::string("bistable-sweep ") + kSoftwareVersion + " (numerics " +
                                               kNumericsVersion + "): " + spec.ModelLabel() + " model, " + settings));
  const std::string merged =
      origin.merged_from_shards > 0
          ? " merged from " + std::to_string(origin.merged_from_shards) + " shards (bistable merge) and"
          : "";
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "history",
                                           IsoTimeUtc(static_cast<double>(std::time(nullptr))) + " bistable-sweep " +
                                               kSoftwareVersion + ": map of sweep " + spec.Id() + merged + " written"));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(
      f, "references",
      "Models and metrics: docs/model.md and docs/numerics.md of bistable-sweep. Paper: Numerical and experimental "
      "studies on a bistable oscillator coupled with a resonator for vibration attenuation and chaos prediction."));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "comment",
                                           "The sweep's spec (TOML) is in the attribute 'spec'; its canonical "
                                           "form, which the sweep id hashes, in 'canonical_spec'."));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "spec", spec.source));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "canonical_spec", spec.CanonicalText()));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "numerics_version", kNumericsVersion));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "software_version", kSoftwareVersion));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "model", spec.ModelLabel()));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "time_unit", dimensional ? "s" : "tau = omega_n t"));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "sweep_id", spec.Id()));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "name", spec.name));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "axes", axes_attr));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "motion_codes", MotionCodesText()));
  if (origin.merged_from_shards > 0) {  // provenance: the records came from that many shard stores
    const int32_t shards = origin.merged_from_shards;
    BISTABLE_RETURN_IF_ERROR(WriteNumberAttr(f, "merged_from_shards", H5T_NATIVE_INT32, &shards, 1));
  }
  // Where it was written: the CPU and the lanes the engine ran there (dynamics/host_lanes.h). host_*: names
  // that say where a file was made, which compare-maps.py skips (a map computed elsewhere is the same map).
  const HostLanes host = ThisHostLanes();
  const int32_t lanes = host.lanes;
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "host_cpu_model", host.cpu_model));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(f, "host_simd_isa", host.isa));
  BISTABLE_RETURN_IF_ERROR(WriteNumberAttr(f, "host_lane_width", H5T_NATIVE_INT32, &lanes, 1));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(
      f, "host_note",
      "host_cpu_model, host_simd_isa and host_lane_width describe the process that wrote this file (" +
          HostLanesLine(host) +
          "). `bistable run` computed its records there; through a coordinator its workers did, possibly on other "
          "CPUs, and records may come from the point cache. No stored number depends on them: a lane's bits are the "
          "same at every lane width."));
  BISTABLE_RETURN_IF_ERROR(WriteStringAttr(
      f, "definitions",
      "See docs/numerics.md. Non-dimensional: tau = omega_n t, lengths in delta_s. Window tau in [t_keep, t_end]. "
      "EDR ratios use the gross injected energy W_in = integral of max(P, 0)."));
  return Status::Ok();
}

Status WriteInto(const Handle& file, const std::string& tmp, const SweepSpec& spec,
                 const std::vector<PointRecord>& records, const RefinedGrid* refined, const MapOrigin& origin) {
  const SweepKind& kind = KindOf(spec);
  MapLayout layout;
  BISTABLE_RETURN_IF_ERROR(WriteAxesAndFixed(file.get(), spec, kind, &layout));
  BISTABLE_RETURN_IF_ERROR(WriteMetricVariables(file.get(), spec, records, layout));
  if (std::find(spec.metrics.begin(), spec.metrics.end(), "hd_peaks") != spec.metrics.end())
    BISTABLE_RETURN_IF_ERROR(WriteHdPeaks(file.get(), spec, records, layout));
  if (spec.base.metrics.turning_points) BISTABLE_RETURN_IF_ERROR(WriteTurningPoints(file.get(), spec, records, layout));
  if (const int np_section = spec.base.metrics.poincare_points; np_section > 0)
    BISTABLE_RETURN_IF_ERROR(WritePoincareSection(file.get(), spec, records, layout, np_section));
  BISTABLE_RETURN_IF_ERROR(WriteKindPart(file.get(), spec, kind.MapPart(spec, records, refined), layout.axis_dims,
                                         layout.axis_names, layout.dims, layout.names, layout.coordinates));
  const hid_t f = file.get();
  BISTABLE_RETURN_IF_ERROR(WriteProvenanceAttributes(f, spec, origin, layout.axes_attr));
  if (H5Fflush(f, H5F_SCOPE_GLOBAL) < 0) return H5Fail(tmp, "flush");
  return Status::Ok();
}

// Writes `bytes` to a new file `path` (mode kDataFileMode, 0640); a full disk is said as such.
Status WriteFileBytes(const std::string& path, const std::vector<char>& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, static_cast<mode_t>(kDataFileMode));
  if (fd < 0) return Status::IoError("map", "create '" + path + "': " + std::strerror(errno));
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      return Status::IoError("map", "write '" + path + "': " + (err == ENOSPC || err == EDQUOT ? "disk full (" : "(") +
                                        std::strerror(err) + ")");
    }
    done += static_cast<size_t>(n);
  }
  if (::close(fd) != 0) {
    const int err = errno;
    return Status::IoError("map", "close '" + path + "': " + (err == ENOSPC || err == EDQUOT ? "disk full (" : "(") +
                                      std::strerror(err) + ")");
  }
  return Status::Ok();
}

// Builds the map file in memory (HDF5's core driver, no backing store) and writes its image to `tmp`
// with plain write(2). HDF5 itself never touches the disk: with its own file driver a full disk made
// a create or a close fail, and HDF5 1.10 keeps a file whose close failed registered half torn down, so
// its exit handler (H5_term_library) crashed closing it again — SIGSEGV after the disk-full error had
// been printed (issue 39). The image is the compressed file (smaller than the records it holds).
Status WriteAll(const std::string& tmp, const SweepSpec& spec, const std::vector<PointRecord>& records,
                const RefinedGrid* refined, const MapOrigin& origin) {
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  if (!fapl.ok() || H5Pset_fapl_core(fapl.get(), size_t{8} << 20, /*backing_store=*/0) < 0)
    return H5Fail(tmp, "core driver");
  const hid_t id = H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (id < 0) return H5Fail(tmp, "create");
  Status st;
  {
    const Handle file(id, [](hid_t) -> herr_t { return 0; });   // closed below, checked
    st = WriteInto(file, tmp, spec, records, refined, origin);  // every other handle is closed when it returns
  }
  std::vector<char> image;
  if (st.ok()) {
    const ssize_t size = H5Fget_file_image(id, nullptr, 0);
    if (size < 0) {
      st = H5Fail(tmp, "file image");
    } else {
      image.resize(static_cast<size_t>(size));
      if (H5Fget_file_image(id, image.data(), image.size()) != size) st = H5Fail(tmp, "file image");
    }
  }
  if (H5Fclose(id) < 0 && st.ok()) st = H5Fail(tmp, "close");  // in memory: nothing left to write
  if (!st.ok()) return st;
  return WriteFileBytes(tmp, image);
}

}  // namespace

namespace {
Status WriteMapFileImpl(const std::string& path, const SweepSpec& spec, const std::vector<PointRecord>& records,
                        const RefinedGrid* refined, const MapOrigin& origin) {
  if (records.size() != static_cast<size_t>(spec.points()) * spec.ic_count())
    return Status::Internal("map file: record count does not match the grid");
  // A temporary of this writer's own (process id and a counter): two processes publishing the same sweep
  // into one data directory each rename a whole file, never one the other is still writing.
  static std::atomic<unsigned long> serial{0};
  const std::string tmp =
      path + "." + std::to_string(static_cast<long>(getpid())) + "-" + std::to_string(++serial) + ".tmp";
  Status st;
  {
    std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors come back as Status, not printed
    st = WriteAll(tmp, spec, records, refined, origin);
  }
  if (st.ok()) st = FsyncPath(tmp, false);
  if (st.ok()) {
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) st = Status::IoError("map", "rename to '" + path + "': " + ec.message());
  }
  if (st.ok()) st = FsyncPath(std::filesystem::path(path).parent_path().string(), true);
  if (!st.ok()) std::filesystem::remove(tmp);
  return st;
}
}  // namespace

Status WriteMapFile(const std::string& path, const SweepSpec& spec, const std::vector<PointRecord>& records,
                    const MapOrigin& origin) {
  return WriteMapFileImpl(path, spec, records, nullptr, origin);
}

Status WriteMapFile(const std::string& path, const SweepSpec& spec, const RefinedGrid& refined) {
  return WriteMapFileImpl(path, spec, refined.records, &refined, MapOrigin{});
}

std::string MapShape(const SweepSpec& spec) {
  std::string shape;
  for (const Axis& a : spec.axes) {
    if (!shape.empty()) shape += 'x';
    shape += std::to_string(a.values.size());
  }
  if (spec.ic_count() > 1) shape += 'x', shape += std::to_string(spec.ic_count());
  return shape;
}

StatusOr<std::vector<std::string>> ListMapMetrics(const std::string& path) {
  std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) return Status::IoError("map", "cannot open map file '" + path + "'");
  std::vector<std::string> names;
  H5Literate(
      file.get(), H5_INDEX_NAME, H5_ITER_NATIVE, nullptr,
      [](hid_t g, const char* name, const H5L_info_t*, void* out) -> herr_t {
        Handle ds(H5Dopen2(g, name, H5P_DEFAULT), H5Dclose);
        if (!ds.ok() || H5DSis_scale(ds.get()) > 0) return 0;
        Handle space(H5Dget_space(ds.get()), H5Sclose);  // fixed parameters are scalars, not metrics
        if (space.ok() && H5Sget_simple_extent_ndims(space.get()) > 0)
          static_cast<std::vector<std::string>*>(out)->push_back(name);
        return 0;
      },
      &names);
  return names;
}

StatusOr<std::string> ReadMapAttribute(const std::string& path, const std::string& name) {
  std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) return Status::IoError("map", "cannot open map file '" + path + "'");
  if (H5Aexists(file.get(), name.c_str()) > 0) {  // a scalar integer (host_lane_width, refine_points_*) as its digits
    Handle attr(H5Aopen(file.get(), name.c_str(), H5P_DEFAULT), H5Aclose);
    Handle type(H5Aget_type(attr.get()), H5Tclose);
    Handle space(H5Aget_space(attr.get()), H5Sclose);
    long long v = 0;
    if (H5Tget_class(type.get()) == H5T_INTEGER && H5Sget_simple_extent_npoints(space.get()) == 1 &&
        H5Aread(attr.get(), H5T_NATIVE_LLONG, &v) >= 0)
      return std::to_string(v);
  }
  return ReadStringAttr(file.get(), name.c_str());
}

// flag_values / flag_meanings of a code dataset, when both are there and agree in count (bounded).
void ReadCategories(hid_t ds, std::vector<std::pair<int, std::string>>* out) {
  if (H5Aexists(ds, "flag_values") <= 0) return;
  Handle attr(H5Aopen(ds, "flag_values", H5P_DEFAULT), H5Aclose);
  Handle space(H5Aget_space(attr.get()), H5Sclose);
  const hssize_t n = space.ok() ? H5Sget_simple_extent_npoints(space.get()) : -1;
  if (n <= 0 || n > 4096) return;
  std::vector<int32_t> values(static_cast<size_t>(n));
  if (H5Aread(attr.get(), H5T_NATIVE_INT32, values.data()) < 0) return;
  const std::string meanings = ReadStringAttr(ds, "flag_meanings");
  std::vector<std::string> words;
  size_t start = 0;
  while (start < meanings.size()) {
    size_t end = meanings.find(' ', start);
    if (end == std::string::npos) end = meanings.size();
    if (end > start) words.push_back(meanings.substr(start, std::min<size_t>(end - start, 128)));
    start = end + 1;
  }
  if (words.size() != values.size()) return;
  for (size_t k = 0; k < values.size(); ++k) out->emplace_back(values[k], words[k]);
}

StatusOr<MapArray> ReadMapMetric(const std::string& path, const std::string& metric) {
  std::lock_guard<std::recursive_mutex> lock(Hdf5Mutex());
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) return Status::IoError("map", "cannot open map file '" + path + "'");
  // The name may come from a remote client: only one of the map's own metric datasets is opened,
  // never an HDF5 path ("/", "..", "/axes/alpha"), an axis scale or a name with NUL or newline.
  auto names = ListMapMetrics(path);
  if (!names.ok()) return names.status();
  BISTABLE_RETURN_IF_ERROR(CheckMetricName(metric, *names));
  MapArray out;
  out.metric = metric;
  Handle ds(H5Dopen2(file.get(), metric.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds.ok()) return Status::IoError("map", "cannot open dataset " + metric + " in '" + path + "'");
  Handle space(H5Dget_space(ds.get()), H5Sclose);
  const int rank = space.ok() ? H5Sget_simple_extent_ndims(space.get()) : -1;
  if (rank < 1 || rank > 32) return Status::IoError("map", "dataset " + metric + " in '" + path + "' has a bad shape");
  std::vector<hsize_t> dims(rank);
  H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  size_t total = 1;
  for (hsize_t d : dims) {
    if (__builtin_mul_overflow(total, static_cast<size_t>(d), &total) || total > limits::kMaxMapValuesRead)
      return Status::IoError("map", "dataset " + metric + " in '" + path + "' is too large");
    out.dims.push_back(d);
  }
  out.values.resize(total);
  if (H5Dread(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.values.data()) < 0)
    return Status::IoError("map", "read " + metric + " from '" + path + "'");
  out.unit = ReadStringAttr(ds.get(), "unit_label");                   // the plots' label; "units" is CF's
  if (out.unit.empty()) out.unit = ReadStringAttr(ds.get(), "units");  // maps written before CF metadata
  out.definition = ReadStringAttr(ds.get(), "definition");
  ReadCategories(ds.get(), &out.categories);
  const std::string axes = ReadStringAttr(file.get(), "axes");
  size_t start = 0;
  while (start < axes.size()) {
    size_t end = axes.find(',', start);
    if (end == std::string::npos) end = axes.size();
    Axis a{axes.substr(start, end - start), {}};
    Handle sd(H5Dopen2(file.get(), a.name.c_str(), H5P_DEFAULT), H5Dclose);
    Handle ss(H5Dget_space(sd.get()), H5Sclose);
    hsize_t n = 0;
    if (!sd.ok() || !ss.ok() || H5Sget_simple_extent_ndims(ss.get()) != 1 ||
        H5Sget_simple_extent_dims(ss.get(), &n, nullptr) < 0 || n > limits::kMaxMapValuesRead)
      return Status::IoError("map", "axis '" + Printable(a.name) + "' of '" + path + "' is missing or malformed");
    a.values.resize(n);
    H5Dread(sd.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, a.values.data());
    const size_t k = out.axes.size();
    if (k >= dims.size() || dims[k] != n)
      return Status::IoError(
          "map", "dataset " + metric + " in '" + path + "' does not match its axis '" + Printable(a.name) + "'");
    out.axes.push_back(a);
    out.dim_names.push_back(a.name);
    start = end + 1;
  }
  for (size_t k = out.axes.size(); k < dims.size(); ++k) {
    char label[64] = "";
    H5DSget_label(ds.get(), static_cast<unsigned>(k), label, sizeof label);
    out.dim_names.push_back(label[0] ? label : (k + 1 == dims.size() ? "peak" : "ic"));
  }
  return out;
}

}  // namespace bistable
