// Synthetic harvester-like records for the identification tests: base acceleration in, absolute velocity and
// voltage out, made by the identification's own simulator (so that the true model reproduces them to the noise).
#ifndef BISTABLE_TESTS_IDENTIFY_SYNTHETIC_H_
#define BISTABLE_TESTS_IDENTIFY_SYNTHETIC_H_

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "identify/fit.h"
#include "identify/model.h"

namespace bistable_test {

using namespace bistable;

// The harvester's form: base acceleration in, absolute velocity and voltage out, per unit mass.
inline bistable::Setup HarvesterSetup() {
  bistable::Setup s;
  s.input = InputKind::kBaseAcceleration;
  s.output = OutputKind::kVelocity;
  s.frame = OutputFrame::kAbsolute;
  return s;
}

inline IdentModel Model(const std::string& terms, std::vector<double> theta) {
  IdentModel m;
  m.terms = *ParseTerms(terms);
  m.m_main = 1.0;
  m.theta = std::move(theta);
  return m;
}

// A record simulated by the model itself: a 6.5 Hz base acceleration (with a harmonic), velocity and
// voltage from a first simulation started at rest, then prepared again from those outputs.
// `drive`: amplitude of the 6.5 Hz base acceleration [m/s²].
inline PreparedRecord SyntheticRecord(const IdentModel& m, double seconds, double fs, double noise_v = 0,
                                      double noise_w = 0, double drive = 1.1) {
  Record rec;
  rec.dt = 1.0 / fs;
  const int n = static_cast<int>((seconds + 8.0) * fs), begin = static_cast<int>(8.0 * fs);
  for (int i = 0; i < n; ++i) {
    const double t = i * rec.dt;
    rec.t.push_back(t);
    rec.input.push_back(drive * std::sin(2 * M_PI * 6.5 * t) + 0.08 * std::sin(2 * M_PI * 13 * t + 0.4));
    rec.output.push_back(1e-3 * std::sin(2 * M_PI * 6.5 * t));  // placeholder, replaced below
    rec.voltage.push_back(1e-3 * std::cos(2 * M_PI * 6.5 * t));
  }
  const bistable::Setup s = HarvesterSetup();
  // The record's initial state comes from its outputs (integrated velocity, local fits): the record is
  // the last `seconds` of a simulation 8 s longer, whose transient has died out by then. Whole periods
  // of the drive in both (seconds a multiple of 2 s), so that the base velocity integrated from the
  // acceleration (zero-mean) is the same over the record as over the simulation.
  SimOutputs so;
  auto first = PrepareRecord(rec, s, 0, rec.t.size(), 0.0, "synthetic");
  EXPECT_TRUE(first.ok()) << first.status().ToString();
  EXPECT_TRUE(SimulateOutputs(m, m.theta, {}, *first, s, 0, 0, false, &so));
  unsigned state = 7;
  auto gauss = [&] {  // Box–Muller on a small LCG: reproducible everywhere
    auto u = [&] { return ((state = state * 1664525u + 1013904223u) >> 8) / 16777216.0 + 1e-9; };
    return std::sqrt(-2 * std::log(u())) * std::cos(2 * M_PI * u());
  };
  for (int i = 0; i < n; ++i)
    rec.output[i] = so.out[0][i] + noise_v * gauss(), rec.voltage[i] = so.out[2][i] + noise_w * gauss();
  auto p = PrepareRecord(rec, s, begin, rec.t.size(), 0.0, "synthetic");
  EXPECT_TRUE(p.ok()) << p.status().ToString();
  return *p;
}

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_IDENTIFY_SYNTHETIC_H_
