#pragma once
// Enumerations between the contracts (protos/mav/v1) and the libraries: one table per enum, read
// both ways. Refusals are worded from the enum's generated descriptor (the names protoc wrote),
// so no decoder keeps a hand-typed list of the values it knows, and every service words the same
// refusal the same way:
//   "<field>: unknown value 7 (known: CONSTANT=1, ALONG_PATH=2, SEGMENT=3)"
//   "<field>: not set (LOCALIZATION_METHOD_UNSPECIFIED); use SPARSE_PIXEL, SPARSE_SUBPIXEL or
//   DENSE"

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "mav/common/status.h"

namespace google::protobuf {
class EnumDescriptor;
}  // namespace google::protobuf

namespace mav::service_common {

using EnumDescriptorFn = const google::protobuf::EnumDescriptor* (*)();

// InvalidArgument "<field>: unknown value V (known: A=1, B=2)": every value of the enum but its
// zero (*_UNSPECIFIED), named without the prefix the enum's values share.
Status UnknownEnumValue(const google::protobuf::EnumDescriptor* descriptor, int value,
                        const std::string& field);

// InvalidArgument "<field>: not set (<ZERO_NAME>); use A, B or C".
Status EnumNotSet(const google::protobuf::EnumDescriptor* descriptor, const std::string& field);

// The name of `value` without the shared prefix ("ALONG_PATH"), or its number when unknown.
std::string EnumValueName(const google::protobuf::EnumDescriptor* descriptor, int value);

template <typename Proto, typename Lib>
struct EnumEntry {
  Proto proto;
  Lib lib;
};

// One enum's table. `entries` pairs each proto value but the zero with its library value (the
// first entry of a library value is the one written back); the zero decodes to `unspecified`,
// or is refused as not set when that is empty. tests/unit/services/proto_codec_test.cc checks
// every table against its descriptor.
template <typename Proto, typename Lib, size_t N>
struct EnumCodec {
  EnumDescriptorFn descriptor;
  std::array<EnumEntry<Proto, Lib>, N> entries;
  std::optional<Lib> unspecified;

  Result<Lib> FromProto(int value, const std::string& field) const {
    if (value == 0) {
      if (unspecified.has_value()) return *unspecified;
      return EnumNotSet(descriptor(), field);
    }
    for (const EnumEntry<Proto, Lib>& e : entries) {
      if (static_cast<int>(e.proto) == value) return e.lib;
    }
    return UnknownEnumValue(descriptor(), value, field);
  }

  // The proto value written for `lib`; the zero for a value the table does not name.
  Proto ToProto(Lib lib) const {
    for (const EnumEntry<Proto, Lib>& e : entries) {
      if (e.lib == lib) return e.proto;
    }
    return static_cast<Proto>(0);
  }
};

// Whether `value` is a value of the enum; the enum's values but the zero, in declaration order.
bool EnumValueKnown(const google::protobuf::EnumDescriptor* descriptor, int value);
std::vector<int> EnumValues(const google::protobuf::EnumDescriptor* descriptor);

// Whether a table covers its enum: every value of the descriptor but the zero decodes, every
// entry names a value of the descriptor other than the zero, and a decoded value is written back
// as an entry that decodes to it again. Internal naming the first value that fails.
template <typename Proto, typename Lib, size_t N>
Status CheckEnumCodec(const EnumCodec<Proto, Lib, N>& codec) {
  const google::protobuf::EnumDescriptor* d = codec.descriptor();
  for (const EnumEntry<Proto, Lib>& e : codec.entries) {
    const int v = static_cast<int>(e.proto);
    if (v == 0 || !EnumValueKnown(d, v)) {
      return Status::Internal("entry " + std::to_string(v) + ": not a set value of the enum");
    }
  }
  for (int v : EnumValues(d)) {
    Result<Lib> lib = codec.FromProto(v, "value");
    if (!lib.ok()) return Status::Internal(EnumValueName(d, v) + ": " + lib.status().message());
    Result<Lib> again = codec.FromProto(static_cast<int>(codec.ToProto(*lib)), "value");
    if (!again.ok() || *again != *lib) {
      return Status::Internal(EnumValueName(d, v) + ": written back as another value");
    }
  }
  return Status::Ok();
}

// Deduces the table's size: MakeEnumCodec<v1::YawPolicy, YawPolicy>(descriptor, {{...}}, k).
template <typename Proto, typename Lib, size_t N>
constexpr EnumCodec<Proto, Lib, N> MakeEnumCodec(
    EnumDescriptorFn descriptor, const EnumEntry<Proto, Lib> (&entries)[N],
    std::type_identity_t<std::optional<Lib>> unspecified) {
  EnumCodec<Proto, Lib, N> codec{descriptor, {}, unspecified};
  for (size_t i = 0; i < N; ++i) codec.entries[i] = entries[i];
  return codec;
}

}  // namespace mav::service_common
