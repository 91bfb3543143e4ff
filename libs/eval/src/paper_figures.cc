#include "mav/eval/paper_figures.h"

#include <fstream>

namespace mav::eval {

std::optional<int> PaperDataSetIndex(const std::string& preset) {
  if (preset == "room-easy") return 0;
  if (preset == "room-medium") return 1;
  if (preset == "room-hard") return 2;
  return std::nullopt;
}

std::string ReadPresetName(const std::string& data) {
  std::ifstream in(data + "/ground_truth/scenario.yaml");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("preset:", 0) == 0) {
      std::string value = line.substr(7);
      value.erase(0, value.find_first_not_of(" \"'"));
      value.erase(value.find_last_not_of(" \"'\r") + 1);
      return value;
    }
  }
  return "";
}

const std::array<PaperLocalizationRow, 3>& PaperLocalization() {
  // Table 1 (runtime, error per data set) and Table 2 (DS3 error per segment length), plus the
  // DS3 end-point errors quoted in the text.
  static const std::array<PaperLocalizationRow, 3> kRows = {{
      {"sparse-pixel",
       {26, 26, 23},
       {1.8, 3.0, 6.2},
       {7.7, 6.6, 6.3, 6.9, 7.1, 7.0, 4.6, 3.6},
       2.41},
      {"sparse-subpixel",
       {34, 33, 30},
       {1.6, 1.4, 3.4},
       {4.5, 3.6, 3.4, 3.6, 3.6, 3.5, 2.8, 2.1},
       1.15},
      {"dense", {49, 52, 52}, {1.5, 2.2, 5.9}, {11.8, 7.6, 5.9, 5.6, 5.7, 5.6, 2.9, 2.4}, 2.08},
  }};
  return kRows;
}

const std::array<PaperMappingRow, 3>& PaperMapping() {
  static const std::array<PaperMappingRow, 3> kRows = {{
      {2839, 214, 0.514, 0.886, 73, 30, {27.57, 0.00, 54.13, 18.29}, {5.78, 0.11, 54.02, 40.07}},
      {1559, 284, 0.589, 0.896, 82, 23, {23.76, 0.00, 51.84, 24.40}, {4.67, 0.67, 51.17, 43.49}},
      {2079, 432, 0.581, 0.938, 115, 31, {24.17, 0.00, 52.30, 23.53}, {2.75, 0.39, 51.90, 44.95}},
  }};
  return kRows;
}

const PaperControlFigures& PaperControl() {
  static const PaperControlFigures kFigures;
  return kFigures;
}

}  // namespace mav::eval
