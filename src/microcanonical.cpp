// Explicit instantiations of pendavg/microcanonical.hpp (filled in by the microcanonical work).
