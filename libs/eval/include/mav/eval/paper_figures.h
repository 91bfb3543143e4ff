#pragma once
// The reference paper's published figures (Holzmann et al., OAGM 2015, arXiv 1505.01065),
// printed beside ours.

#include <array>
#include <optional>
#include <string>

namespace mav::eval {

// Data sets 1..3 of the paper correspond to our room-easy, room-medium, room-hard presets.
// Returns 0-based index, or nullopt for other data.
std::optional<int> PaperDataSetIndex(const std::string& preset);

// The preset name of a data set mav-sim generated: `preset:` of <data>/ground_truth/scenario.yaml;
// empty when the file or the key is absent (recorded data).
std::string ReadPresetName(const std::string& data);

struct PaperLocalizationRow {
  const char* method;  // our method name
  std::array<double, 3> runtime_ms;
  std::array<double, 3> error_pct;
  std::array<double, 8> ds3_error_per_length_pct;  // Table 2: 2 5 10 15 20 25 60 75 m
  double ds3_end_point_error_m;
};

const std::array<PaperLocalizationRow, 3>& PaperLocalization();

// Tables 3 and 4 (mapping), one row per data set.
struct PaperMappingRow {
  int frames;
  int keyframes;
  double mcc_octomap;
  double mcc_ours;
  double runtime_octomap_s;
  double runtime_ours_s;
  // Table 4, percent of box positions, in the order false-collision, missed-collision,
  // correct-collision, correct-free.
  std::array<double, 4> outcomes_octomap_pct;
  std::array<double, 4> outcomes_ours_pct;
};

const std::array<PaperMappingRow, 3>& PaperMapping();

// Section 3's control and planning results: hover, wind, and "Paths of 35 m are planned in
// 0.75 s and can be safely executed in 7.55-8.8 s with average speeds of 4.2 m/s and peak speeds
// of 7.70 m/s".
struct PaperControlFigures {
  double hover_position_rms_m = 0.055;
  double hover_angular_rate_rms_radps = 0.087;
  double constant_wind_settling_s = 3.6;  // "rejected in 3.6 s"; any wind "in less than 4 s"
  double leg_length_m = 35;
  double leg_flight_time_min_s = 7.55, leg_flight_time_max_s = 8.8;
  double leg_mean_speed_mps = 4.2;
  double leg_peak_speed_mps = 7.70;
  double plan_time_s = 0.75;
};

const PaperControlFigures& PaperControl();

}  // namespace mav::eval
