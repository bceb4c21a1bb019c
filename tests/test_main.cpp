// SPDX-License-Identifier: GPL-3.0-or-later
// Catch2 entry point for pendavg_tests.
#define CATCH_CONFIG_MAIN
#include <catch2/catch.hpp>
