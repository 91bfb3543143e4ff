#pragma once
// Names of EuRoC's folders, files and CSV columns (internal to this library).

#include <string>
#include <vector>

namespace mav::dataset::internal {

inline const std::vector<std::string>& CameraColumns() {
  static const std::vector<std::string> kColumns = {"#timestamp [ns]", "filename"};
  return kColumns;
}

inline const std::vector<std::string>& ImuColumns() {
  static const std::vector<std::string> kColumns = {
      "#timestamp [ns]",   "w_RS_S_x [rad s^-1]", "w_RS_S_y [rad s^-1]", "w_RS_S_z [rad s^-1]",
      "a_RS_S_x [m s^-2]", "a_RS_S_y [m s^-2]",   "a_RS_S_z [m s^-2]"};
  return kColumns;
}

inline const std::vector<std::string>& GroundTruthColumns() {
  static const std::vector<std::string> kColumns = {"#timestamp",
                                                    "p_RS_R_x [m]",
                                                    "p_RS_R_y [m]",
                                                    "p_RS_R_z [m]",
                                                    "q_RS_w []",
                                                    "q_RS_x []",
                                                    "q_RS_y []",
                                                    "q_RS_z []",
                                                    "v_RS_R_x [m s^-1]",
                                                    "v_RS_R_y [m s^-1]",
                                                    "v_RS_R_z [m s^-1]",
                                                    "b_w_RS_S_x [rad s^-1]",
                                                    "b_w_RS_S_y [rad s^-1]",
                                                    "b_w_RS_S_z [rad s^-1]",
                                                    "b_a_RS_S_x [m s^-2]",
                                                    "b_a_RS_S_y [m s^-2]",
                                                    "b_a_RS_S_z [m s^-2]"};
  return kColumns;
}

inline std::string JoinHeader(const std::vector<std::string>& columns, const char* sep) {
  std::string out;
  for (size_t i = 0; i < columns.size(); ++i) {
    if (i > 0) out += sep;
    out += columns[i];
  }
  return out + "\n";
}

inline constexpr const char* kGroundTruthFolder = "state_groundtruth_estimate0";

}  // namespace mav::dataset::internal
