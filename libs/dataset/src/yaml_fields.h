#pragma once
// The YAML field readers of the dataset's YAML files (task files, mission files): every error is
// an InvalidArgument that names the key path ("forces[0].start_s: 'x' is not a number"); the
// caller prefixes the file. A key is echoed as written only when it looks like one; anything
// else is quoted and truncated (QuoteForError), so a file's text is never echoed whole.
// yaml-cpp throws: callers call these inside a try block that turns YAML::Exception into a Status.

#include <algorithm>
#include <cctype>
#include <set>
#include <string>

#include <yaml-cpp/yaml.h>
#include <Eigen/Core>

#include "mav/common/parse.h"
#include "mav/common/status.h"
#include "mav/common/text.h"

namespace mav::dataset::internal {

class YamlFields {
 public:
  Status CheckKeys(const YAML::Node& map, const std::string& path,
                   const std::set<std::string>& known) const {
    if (!map.IsMap()) return Bad(path, "expected a mapping");
    for (const auto& kv : map) {
      const std::string key = kv.first.as<std::string>();
      if (!known.count(key)) {
        std::string list;
        for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
        return Status::InvalidArgument(Join(path, Shown(key)) + ": unknown key (known: " + list +
                                       ")");
      }
    }
    return Status::Ok();
  }

  Status Double(const YAML::Node& map, const std::string& path, const std::string& key,
                double* out) const {
    const YAML::Node n = map[key];
    if (!n) return Status::Ok();
    if (!n.IsScalar()) return Bad(Join(path, key), "expected a number");
    MAV_ASSIGN_OR_RETURN(*out, ParseDouble(n.Scalar(), Join(path, key)));
    return Status::Ok();
  }

  Status Vector(const YAML::Node& n, const std::string& path, Eigen::Vector3d* out) const {
    if (!n.IsSequence() || n.size() != 3) return Bad(path, "expected a list of 3 numbers");
    for (int i = 0; i < 3; ++i) {
      if (!n[i].IsScalar()) return Bad(path, "expected a list of 3 numbers");
      MAV_ASSIGN_OR_RETURN((*out)[i], ParseDouble(n[i].Scalar(), path));
    }
    return Status::Ok();
  }

  Status Vector(const YAML::Node& map, const std::string& path, const std::string& key,
                Eigen::Vector3d* out) const {
    const YAML::Node n = map[key];
    if (!n) return Status::Ok();
    return Vector(n, Join(path, key), out);
  }

  // A key as the user wrote it when it looks like one (letters, digits, '_', at most 64), else
  // quoted and truncated (QuoteForError): a file's text is never echoed whole.
  static std::string Shown(const std::string& key) {
    const bool plain =
        !key.empty() && key.size() <= 64 && std::all_of(key.begin(), key.end(), [](char c) {
          return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
        });
    return plain ? key : QuoteForError(key);
  }
  static std::string Join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }
  static Status Bad(const std::string& path, const std::string& what) {
    return Status::InvalidArgument(path + ": " + what);
  }
};

}  // namespace mav::dataset::internal
