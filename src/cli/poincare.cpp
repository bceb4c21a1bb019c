// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/poincare.cpp -- `pendavg poincare`: the double pendulum's Poincare section. Thin:
// parse, call the library (poincare_section), fill records (src/io) -> CSV, JSON or text.
// SIGINT/SIGTERM end a run early and the points so far are printed (interrupted true); --output
// is written atomically.
#include "common.hpp"

#include "average_options.hpp"
#include "interrupt.hpp"

#include "io/record.hpp"
#include "io/report.hpp"
#include "io/results.hpp"

#include "pendavg/pendavg.hpp"

#include <array>
#include <cstdio>
#include <string>
#include <string_view>

namespace pendavg::cli {

namespace {

constexpr std::string_view poincare_usage =
    "usage: pendavg poincare --masses M1,M2 --lengths L1,L2 [--g G] --energy E\n"
    "                        [--orbits K] [--points P] [--dt H] [--format csv|json|text]\n"
    "                        [--output FILE]\n"
    "\n"
    "The double pendulum's Poincare section phi_1 = 0, phidot_1 > 0 (paper Appendix E) at\n"
    "energy E (paper's U convention; E > -(M l1 + m2 l2) g): K orbits (default 8) started on\n"
    "the section, P crossings each (default 500), time step H (default 1e-3).\n"
    "Output (schema 1, README: Output schema): the run -- N, g, m, l, energy, orbits,\n"
    "points_per_orbit, dt, steps, energy_error_max, interrupted, seconds -- and one record per\n"
    "crossing: orbit (0-based), phi2, p2 (the canonical momentum), time. CSV (default): a\n"
    "'# schema: 1' line, a '# pendavg poincare' line, the header, then one row per crossing\n"
    "(the run's columns first, the same on every row); JSON: the run's keys and \"points\": an\n"
    "array of {orbit, phi2, p2, time}; text: the run, then the crossings as a table. Numbers are\n"
    "the shortest decimals that read back as the same double. To stdout, or atomically to\n"
    "--output FILE (nothing on stdout).\n";

std::string run_poincare(const Options& options) {
  const Chain<double> chain = dynamics_chain_option(options);
  if (chain.size() != 2) throw usage_error("poincare: the section is for N = 2 (two masses)");
  const double energy = parse_real<double>(options.required("energy"), "--energy", Domain::any);
  PoincareOptions run;
  run.orbits = static_cast<std::size_t>(
      parse_integer(options.get("orbits", "8"), "--orbits", 1, 10000));
  run.points = static_cast<std::size_t>(
      parse_integer(options.get("points", "500"), "--points", 1, 100000000));
  run.time_step = parse_real<double>(options.get("dt", "1e-3"), "--dt", Domain::positive);
  run.threads = hardware_threads();
  const Format format = format_option(options, "csv", all_formats);
  check_output_option(options, "poincare");
  input_checked("poincare");
  const Stopwatch stopwatch;
  Progress progress("poincare");
  DynamicsObserver<double> observer;
  observer.progress = [&](double fraction) { progress(fraction, "of the section points "); };
  StopOnSignal signals;
  observer.stop = &stop_flag();
  const PoincareSection<double> section = poincare_section(chain, energy, run, observer);
  if (section.interrupted) std::fprintf(stderr, "[poincare] interrupted: points so far\n");
  io::Record head(io::poincare_fields(), chain.size());
  io::append_poincare(head, chain, run, section, input_texts(options, "energy", chain.size()));
  const io::ListReport report{
      "poincare",
      {&head},
      "points",
      io::section_point_fields(),
      section.points.size(),
      [&](std::size_t k, io::Record& point) { io::append_section_point(point, section.points[k]); },
      stopwatch.seconds()};
  return deliver(options, "poincare", io::format_list_report(report, format));
}

}  // namespace

constexpr std::array<std::string_view, 9> poincare_options{
    "masses", "lengths", "g", "energy", "orbits", "points", "dt", "format", "output"};
const Command poincare_command{"poincare", poincare_usage, poincare_options, run_poincare};

}  // namespace pendavg::cli
