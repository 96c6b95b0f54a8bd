#include "dynamics/ensemble_generic.h"
#include "dynamics/ensemble_rosenbrock.h"

namespace bistable {
namespace {

template <int W, int kCells>
bool RunSeriesChain(const SeriesLaneInput* in, int n, const KernelSettings& s, RawLane* out) {
  if (in[0].cells.front().has_resonator)
    return EnsembleGeneric<SeriesLaneModel<kCells, true>, W>::Run(in, n, s, 1, out);
  return EnsembleGeneric<SeriesLaneModel<kCells, false>, W>::Run(in, n, s, 1, out);
}

}  // namespace

template <int W>
bool RunSeriesLanes(const SeriesLaneInput* in, int n, const KernelSettings& s, RawLane* out) {
  switch (in[0].cells.size()) {
    case 1:
      return RunSeriesChain<W, 1>(in, n, s, out);
    case 2:
      return RunSeriesChain<W, 2>(in, n, s, out);
    case 3:
      return RunSeriesChain<W, 3>(in, n, s, out);
    case 4:
      return RunSeriesChain<W, 4>(in, n, s, out);
    default:
      return RunSeriesChain<W, 0>(in, n, s, out);
  }
}

template <int W>
bool RunDimensionalLanes(const DimensionalLaneInput* in, int n, const KernelSettings& s, int substeps, RawLane* out) {
  return EnsembleGeneric<DimensionalLaneModel, W>::Run(in, n, s, substeps, out);
}

template <int W>
bool RunTermLanes(const TermLaneInput* in, int n, const KernelSettings& s, int substeps, RawLane* out) {
  return EnsembleGeneric<TermLaneModel, W>::Run(in, n, s, substeps, out);
}

template <int W>
bool RunDimensionalRosenbrock(const DimensionalLaneInput* in, int n, const KernelSettings& s,
                              const RosenbrockTolerances& tol, RawLane* out) {
  return EnsembleRosenbrock<W>::Run(in, n, s, tol, out);
}

template bool RunSeriesLanes<1>(const SeriesLaneInput*, int, const KernelSettings&, RawLane*);
template bool RunSeriesLanes<4>(const SeriesLaneInput*, int, const KernelSettings&, RawLane*);
template bool RunSeriesLanes<8>(const SeriesLaneInput*, int, const KernelSettings&, RawLane*);
template bool RunDimensionalLanes<1>(const DimensionalLaneInput*, int, const KernelSettings&, int, RawLane*);
template bool RunDimensionalLanes<4>(const DimensionalLaneInput*, int, const KernelSettings&, int, RawLane*);
template bool RunDimensionalLanes<8>(const DimensionalLaneInput*, int, const KernelSettings&, int, RawLane*);
template bool RunTermLanes<1>(const TermLaneInput*, int, const KernelSettings&, int, RawLane*);
template bool RunTermLanes<4>(const TermLaneInput*, int, const KernelSettings&, int, RawLane*);
template bool RunTermLanes<8>(const TermLaneInput*, int, const KernelSettings&, int, RawLane*);
template bool RunDimensionalRosenbrock<1>(const DimensionalLaneInput*, int, const KernelSettings&,
                                          const RosenbrockTolerances&, RawLane*);
template bool RunDimensionalRosenbrock<4>(const DimensionalLaneInput*, int, const KernelSettings&,
                                          const RosenbrockTolerances&, RawLane*);
template bool RunDimensionalRosenbrock<8>(const DimensionalLaneInput*, int, const KernelSettings&,
                                          const RosenbrockTolerances&, RawLane*);

}  // namespace bistable
