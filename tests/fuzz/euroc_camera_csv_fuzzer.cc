// libFuzzer target: mav0/cam0/data.csv (dataset::ParseCameraCsv).

#include "fuzz_checks.h"
#include "mav/dataset/euroc.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const auto rows = dataset::ParseCameraCsv(fuzz::AsText(data, size), fuzz::kName);
  if (!rows.ok()) {
    fuzz::CheckFailure(rows.status());
    return 0;
  }
  MAV_CHECK(rows->t_ns.size() == rows->files.size());
  for (size_t i = 0; i < rows->t_ns.size(); ++i) {
    MAV_CHECK(i == 0 || rows->t_ns[i] > rows->t_ns[i - 1]) << "stamps strictly increase";
    const std::string& f = rows->files[i];
    MAV_CHECK(!f.empty() && f.find('/') == std::string::npos && f != "." && f != "..")
        << "a plain file name: " << f.substr(0, 100);
  }
  return 0;
}
