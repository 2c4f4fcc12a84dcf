#pragma once
/// @file svg_plots.hpp
/// SVG plots of a HIL session: the map with true and estimated trajectories, and the position
/// error versus distance travelled.

#include <string>
#include <vector>

#include "agv/sim/world.hpp"
#include "scenario.hpp"

namespace agv::hil {

/// Map (walls, pallets, racks, pillars, reflectors, paths) with the first run of every path:
/// truth, dead reckoning with the true, the nominal and the estimated parameters. False with `error`
/// when the file cannot be written.
bool writeMapSvg(const std::string& file, const sim::World& world, const std::vector<RunResult>& runs,
                 std::string& error);

/// Position error [m, log scale] versus distance [m] for every run and parameter set, with
/// the 2 cm requirement line. False with `error` when the file cannot be written.
bool writeErrorSvg(const std::string& file, const std::vector<RunResult>& runs, double requirement, std::string& error);

}  // namespace agv::hil
