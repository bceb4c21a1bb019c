// Explicit instantiations of pendavg/dynamics.hpp (filled in by the dynamics work).
