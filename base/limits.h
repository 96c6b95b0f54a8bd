// Every bound that input from a spec, a client, a worker or a data file can run into, in one place.
// Each limit is enforced where the input enters (spec parsing, the gRPC service, the coordinator) and
// its error names the field and this bound. docs/limits.md lists them for users; change both together.
//
// The values are generous for the science (the paper's settings use 5e4 steps per point, 201 x 201
// grids, 10 peaks) and small enough that no single request can take the machine: a sweep's plan is
// at most a few hundred MB, a report a few MB, a point's window buffers tens of MB.
#ifndef BISTABLE_BASE_LIMITS_H_
#define BISTABLE_BASE_LIMITS_H_

#include <cstddef>
#include <cstdint>

namespace bistable::limits {

// --- Specs -----------------------------------------------------------------------------------------
inline constexpr std::size_t kMaxSpecBytes = 1 << 20;  // TOML text of one spec
inline constexpr std::size_t kMaxNameBytes = 200;      // spec `name`, a submit's `origin`
inline constexpr long kMaxSweepItems = 4'194'304;      // grid points x initial conditions (2^22)
// RK4 steps per output step of the rig or a term model under integrator = "rk4" (the friction's transition sets
// them: Table 2 needs 5 at dt = 1 ms); beyond, the spec is refused rather than run for days.
inline constexpr int kMaxRk4Substeps = 1000;
inline constexpr long kMaxAxisValues = 1'048'576;  // values of one axis (2^20)
inline constexpr int kMaxInitialStates = 64;       // initial_conditions.states
inline constexpr int kMaxSeriesCells = 1000;       // series.cells

// --- One point -------------------------------------------------------------------------------------
inline constexpr double kMaxStepsPerPoint = 1e8;              // t_end / dt
inline constexpr double kMaxWindowSamples = 4'194'304;        // (t_end - t_keep) / dt / sample_every
inline constexpr std::size_t kMaxTurningPointsKept = 65'536;  // turning points held per point (the last ones)
// A dashboard cell (/api/cell) is integrated on the coordinator while others wait: at most 10^7 steps
// (about 0.4 s; 200 times the paper's 5·10^4) and 2^20 window samples (its rows are held for the orbit, the
// series and the spectrum). Larger cells are refused (422) with the `bistable point` command that runs them.
inline constexpr double kMaxCellSteps = 1e7;
inline constexpr double kMaxCellSamples = 1'048'576;
inline constexpr int kMaxPeriod = 64;             // [metrics] max_period: longest stroboscopic period sought
inline constexpr long kMaxEvery = 1'000'000'000;  // [metrics] renorm_every, sample_every (steps)
// `bistable point --poincare-periods N`: forcing periods of the section (the window is made N + 1
// periods long). 4 doubles per period: 3.2 MB at the bound; the step and window-sample limits apply too.
inline constexpr long kMaxPoincarePeriods = 100'000;
// Sweeps: section points stored per (point, initial condition), `[metrics] poincare_points`. A report
// of a full lease (kMaxJobItems records of at most 33 + 64 + 2·64 doubles) stays under kMaxMessageBytes.
inline constexpr int kMaxPoincarePointsStored = 64;
// Attractor classes a basin map tells apart (engine/basins.cc): starts beyond them join one "other"
// class, so classification stays O(starts × classes) and the flag_meanings attribute stays small.
inline constexpr int kMaxAttractors = 255;
// Tolerance samples per grid point of a robustness map ([robustness] samples; also bounded by the
// sweep's items: points x samples).
inline constexpr int kMaxRobustnessSamples = 4096;
// Halvings of an adaptive map ([refine] levels: the coarse grid takes every 2^levels-th axis value).
inline constexpr int kMaxRefineLevels = 10;
// `bistable run --shard I/N` (issue 43): shards of one sweep (a job array's tasks; Slurm's default MaxArraySize is
// 1001).
inline constexpr int kMaxShards = 100'000;

// --- Design search (`bistable design`, [design]) ---------------------------------------------------
inline constexpr int kMaxDesignBudget = 10'000;  // candidates one search may evaluate (design.budget)
inline constexpr int kMaxDesignAlphas = 16;      // forcing amplitudes a band must hold at (design.alpha)
inline constexpr int kMaxDesignMaps = 3;         // alpha x omega maps of the best designs (design.maps)
inline constexpr int kMaxBruteForceSide = 64;    // --brute-force N: N values per free parameter
inline constexpr double kMinDesignRatio = 1e-3;  // design.bounds.lambda / .phi in [1e-3, 100]
inline constexpr double kMaxDesignRatio = 100;
inline constexpr double kMinDesignDamping = 0;  // design.bounds.eta_r in [0, 100]
inline constexpr double kMaxDesignDamping = 100;

// --- Harmonic balance (`bistable hbm`) -------------------------------------------------------------
inline constexpr int kMaxHbmHarmonics = 50;         // harmonics of a branch (a switched period-2ν branch too)
inline constexpr int kMaxHbmSwitchedBranches = 64;  // branches switched onto at period doublings
inline constexpr int kMaxHbmFoldCurves = 64;        // fold curves continued in (alpha, Omega)

// --- The service -----------------------------------------------------------------------------------
inline constexpr std::size_t kMaxMessageBytes = 8 << 20;      // any request to the coordinator
inline constexpr std::size_t kMaxJobsPerLease = 16;           // jobs one Lease call may ask for
inline constexpr int kMaxKnownSpecs = 16;                     // spec keys one Lease call may name (and a worker keeps)
inline constexpr std::size_t kMaxMapCacheEntries = 16;        // published metrics and metric lists kept read (server)
inline constexpr std::size_t kMaxMapCacheBytes = 256u << 20;  // their values in all; a larger one is read, not kept
inline constexpr double kMaxLeaseSeconds = 86'400;            // a lease period (--lease-seconds; a worker refuses more)
inline constexpr std::size_t kFetchChunkBytes = 1 << 20;      // map files are streamed in chunks of this
inline constexpr std::uint64_t kMaxFetchBytes = std::uint64_t{1} << 36;  // a fetched map file (64 GiB)
inline constexpr std::size_t kMaxIdBytes = 64;                           // sweep ids / prefixes, lease ids in requests
inline constexpr std::size_t kMaxWorkerNameBytes = 128;                  // a worker's registered name
inline constexpr std::size_t kMaxWorkers = 4096;                         // workers remembered (oldest idle forgotten)
inline constexpr std::size_t kMaxMetricNameBytes = 64;                   // metric names in map requests
inline constexpr int kMaxActiveSweepsPerOwner = 8;                       // queued or running sweeps of one token
inline constexpr int kMaxActiveSweeps = 64;                              // queued or running sweeps in all
inline constexpr long kMaxJobItems = 4096;                               // items in one job (and so in one report)
// Items a worker accepts in one lease: a job closes once it holds its size, and a continuation chain
// (at most kMaxJobItems points) is never split, so a job holds fewer than 2 · kMaxJobItems items.
inline constexpr long kMaxLeaseItems = 2 * kMaxJobItems;
inline constexpr double kMinWatchInterval = 0.25;                 // seconds between two status messages
inline constexpr int kMaxServerThreads = 128;                     // gRPC threads (each open watch holds one)
inline constexpr std::size_t kMaxServerMemoryBytes = 512u << 20;  // gRPC transport buffers in all
inline constexpr std::size_t kMaxTokenFileBytes = 1 << 16;        // a client's --token-file (one bearer token)
// A bearer token as sent (after trailing white space is dropped from a token file): visible ASCII only
// (0x21-0x7e: what an HTTP/2 header value carries; a newline or NUL would make gRPC abort the process).
inline constexpr std::size_t kMaxTokenBytes = 4096;
inline constexpr std::size_t kMaxPemFileBytes = 1 << 20;      // TLS CA, certificate and key files
inline constexpr std::size_t kMaxTokensFileBytes = 16 << 20;  // the coordinator's tokens file (one hash per line)

// --- Queries, map files and measured data ---------------------------------------------------------
inline constexpr std::size_t kMaxQueryBytes = 4096;  // a query expression
inline constexpr int kMaxQueryDepth = 64;            // nesting of parentheses / not
// Values of one dataset read back from a map file: its declared dims are not trusted (a chunked
// dataset can declare far more than it stores); 2^31 doubles is above any map a sweep may write.
inline constexpr std::size_t kMaxMapValuesRead = std::size_t{1} << 31;
// |value| of a measured record, raw and in SI units. Records are far below it (metres, volts, ADC
// counts ~1e7, Unix times ~2e9); beyond it the regression's fifth powers lose every digit or overflow.
inline constexpr double kMaxDataMagnitude = 1e12;
// A line of a measured-record CSV (the header and comments included; a DAQ export with 100 channels
// of 20 digits is 2 KB) and the data rows of one file (2^22: 70 min at 1 kHz; t, input, output and
// resonator then hold 128 MB; the Silverbox file has 131,072 rows).
inline constexpr std::size_t kMaxDataLineBytes = 65'536;
inline constexpr long kMaxDataRows = 4'194'304;
// Records in one data file (a group column's changes, or time restarts): bounds the per-record overhead a
// file of tiny records would otherwise multiply (2 rows each: 2 M records).
inline constexpr long kMaxDataRecords = 4096;
// A fitted model read back by `identify --predict --model FILE` (an `identify --json` output or a
// report.json: a few hundred KB with every step's scores), its JSON nesting (the format nests 5 deep)
// and the size of a parameter value (k5 per unit mass reaches 1e13 on the harvester).
inline constexpr std::size_t kMaxModelJsonBytes = 16u << 20;
inline constexpr int kMaxModelJsonDepth = 64;
inline constexpr double kMaxModelParamMagnitude = 1e100;

// --- Figures --------------------------------------------------------------------------------------
// `bistable map --mark X,Y,LABEL` / `--marks FILE.csv`: marks on one figure (both flags together), the
// characters (code points) of one label, and the size of a marks file (200 rows of 80-character labels
// are ~20 KB; comments included).
inline constexpr int kMaxMapMarks = 200;
inline constexpr std::size_t kMaxMarkLabelChars = 80;
inline constexpr std::size_t kMaxMarksFileBytes = 1 << 20;

}  // namespace bistable::limits

#endif  // BISTABLE_BASE_LIMITS_H_
