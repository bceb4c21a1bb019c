// src/python/module.cpp -- the extension module pendavg._pendavg. Bad input is a
// pendavg::invalid_input (a std::invalid_argument), which pybind11 raises as ValueError with the
// library's or the CLI's one-line message; pendavg::interrupted (a run stopped on Ctrl-C before
// it finished anything) is KeyboardInterrupt; any other C++ exception becomes a Python
// exception too (RuntimeError, MemoryError), never a crash.
#include "bindings.hpp"

#include "pendavg/result.hpp"
#include "pendavg/version.hpp"

PYBIND11_MODULE(_pendavg, m) {
  m.doc() = "pendavg's C++ core; use the package pendavg (its __init__ documents the API).";
  m.attr("__version__") = pendavg::version();
  // A run stopped on Ctrl-C before it finished anything it could report (RunControl).
  pybind11::register_exception_translator([](std::exception_ptr error) {
    try {
      if (error) std::rethrow_exception(error);
    } catch (const pendavg::interrupted& stopped) {
      PyErr_SetString(PyExc_KeyboardInterrupt, stopped.what());
    }
  });
  pendavg::python::expose_average(m);
  pendavg::python::expose_series(m);
  pendavg::python::expose_microcanonical(m);
  pendavg::python::expose_dynamics(m);
}
