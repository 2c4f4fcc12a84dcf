// agvnav-calibrate: on-vehicle calibration routine (STC, ATC, laser pose) on the simulated vehicle.
#include <cstdio>

#include "calibrate_cli.hpp"

int main(int argc, char** argv) {
  return agv::calibration::calibrateMain(argc, argv, stdout, stderr);
}
