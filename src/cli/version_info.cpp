// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/version_info.cpp -- `pendavg --version` (version_info.hpp). A library's run-time version
// (mpfr_get_version(), gmp_version, gsl_version) can differ from the headers the command was
// compiled with when a shared library is updated underneath it, so both are printed.
#include "version_info.hpp"

#include "pendavg/dynamics.hpp"
#include "pendavg/average.hpp"
#include "pendavg/version.hpp"

#include <boost/version.hpp>
#include <gmp.h>
#include <gsl/gsl_version.h>
#include <mpfr.h>

#if defined(PENDAVG_WITH_MPI)
#include <mpi.h>
#endif

#include <string>

namespace pendavg::cli {

namespace {

#define PENDAVG_STRINGIFY2(x) #x
#define PENDAVG_STRINGIFY(x) PENDAVG_STRINGIFY2(x)

std::string mpi_text() {
#if defined(PENDAVG_WITH_MPI)
  // MPI_Get_library_version may be called before MPI_Init and after MPI_Finalize (MPI 3.0).
  char library[MPI_MAX_LIBRARY_VERSION_STRING] = {};
  int length = 0;
  std::string text;
  if (MPI_Get_library_version(library, &length) == MPI_SUCCESS) {
    text.assign(library, static_cast<std::size_t>(length));
    // One line: a library may print several.
    if (const auto end = text.find_first_of("\r\n"); end != std::string::npos) text.resize(end);
    while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.pop_back();
  } else {
    text = "unknown library";
  }
  return text + " (MPI standard " PENDAVG_STRINGIFY(MPI_VERSION) "." PENDAVG_STRINGIFY(
             MPI_SUBVERSION) ")";
#else
  return "no MPI";
#endif
}

std::string instruction_sets() {
  // The kernels built into the library (CMake's PENDAVG_DYNAMICS_DISPATCH) and the one this CPU
  // runs (dynamics_instruction_set(): PENDAVG_DYNAMICS_ISA=base forces the baseline).
  std::string built = "base";
#if defined(PENDAVG_HAVE_DYNAMICS_X86_64_V3)
  built += ", x86-64-v3";
#endif
  return "built " + built + "; selected " + dynamics_instruction_set();
}

std::string compiler() {
#if defined(__clang__)
  return "Clang " __clang_version__;
#elif defined(__GNUC__)
  return "GCC " __VERSION__;
#else
  return "unknown";
#endif
}

}  // namespace

std::string version_text() {
  std::string text = std::string("pendavg ") + version() + "\n";
  text += std::string("git revision: ") + git_revision() + "\n";
  text += "MPI: " + mpi_text() + "\n";
  text += "dynamics instruction sets: " + instruction_sets() + "\n";
  text += "compiler: " + compiler() + ", C++ " PENDAVG_STRINGIFY(__cplusplus) "\n";
  // Boost is used header-only: the version compiled against is the one run with.
  text += "Boost: " + std::to_string(BOOST_VERSION / 100000) + "." +
          std::to_string(BOOST_VERSION / 100 % 1000) + "." + std::to_string(BOOST_VERSION % 100) +
          "\n";
  text += std::string("MPFR: ") + mpfr_get_version() + " (compiled against " MPFR_VERSION_STRING
          ")\n";
  text += std::string("GMP: ") + gmp_version + " (compiled against " +
          std::to_string(__GNU_MP_VERSION) + "." + std::to_string(__GNU_MP_VERSION_MINOR) + "." +
          std::to_string(__GNU_MP_VERSION_PATCHLEVEL) + ")\n";
  text += std::string("GSL: ") + gsl_version + " (compiled against " GSL_VERSION ")\n";
  text += std::string("certified enclosures (--certified): ") +
          (certified_available() ? certified_backend() : "unavailable: " + certified_backend()) +
          "\n";
  return text;
}

}  // namespace pendavg::cli
