#include "services/common/proto_enum.h"

#include <string>
#include <vector>

#include <google/protobuf/descriptor.h>

namespace mav::service_common {

namespace {

// The prefix every value's name shares up to an underscore ("YAW_POLICY_"), found from the
// names themselves so that an enum whose values do not share one keeps them whole.
size_t SharedPrefix(const google::protobuf::EnumDescriptor* d) {
  if (d->value_count() < 2) return 0;
  std::string prefix = d->value(0)->name();
  for (int i = 1; i < d->value_count(); ++i) {
    const std::string& name = d->value(i)->name();
    size_t n = 0;
    while (n < prefix.size() && n < name.size() && prefix[n] == name[n]) ++n;
    prefix.resize(n);
  }
  const size_t underscore = prefix.rfind('_');
  return underscore == std::string::npos ? 0 : underscore + 1;
}

// The named values but the zero, in declaration order.
std::vector<const google::protobuf::EnumValueDescriptor*> SetValues(
    const google::protobuf::EnumDescriptor* d) {
  std::vector<const google::protobuf::EnumValueDescriptor*> out;
  for (int i = 0; i < d->value_count(); ++i) {
    if (d->value(i)->number() != 0) out.push_back(d->value(i));
  }
  return out;
}

}  // namespace

bool EnumValueKnown(const google::protobuf::EnumDescriptor* descriptor, int value) {
  return descriptor->FindValueByNumber(value) != nullptr;
}

std::vector<int> EnumValues(const google::protobuf::EnumDescriptor* descriptor) {
  std::vector<int> out;
  for (const google::protobuf::EnumValueDescriptor* v : SetValues(descriptor)) {
    out.push_back(v->number());
  }
  return out;
}

std::string EnumValueName(const google::protobuf::EnumDescriptor* descriptor, int value) {
  const google::protobuf::EnumValueDescriptor* v = descriptor->FindValueByNumber(value);
  if (v == nullptr) return std::to_string(value);
  return v->name().substr(SharedPrefix(descriptor));
}

Status UnknownEnumValue(const google::protobuf::EnumDescriptor* descriptor, int value,
                        const std::string& field) {
  const size_t prefix = SharedPrefix(descriptor);
  std::string known;
  for (const google::protobuf::EnumValueDescriptor* v : SetValues(descriptor)) {
    known +=
        (known.empty() ? "" : ", ") + v->name().substr(prefix) + "=" + std::to_string(v->number());
  }
  return Status::InvalidArgument(field + ": unknown value " + std::to_string(value) +
                                 " (known: " + known + ")");
}

Status EnumNotSet(const google::protobuf::EnumDescriptor* descriptor, const std::string& field) {
  const size_t prefix = SharedPrefix(descriptor);
  const std::vector<const google::protobuf::EnumValueDescriptor*> values = SetValues(descriptor);
  std::string use;
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) use += i + 1 == values.size() ? " or " : ", ";
    use += values[i]->name().substr(prefix);
  }
  const google::protobuf::EnumValueDescriptor* zero = descriptor->FindValueByNumber(0);
  return Status::InvalidArgument(field + ": not set (" +
                                 (zero != nullptr ? zero->name() : std::string("0")) + "); use " +
                                 use);
}

}  // namespace mav::service_common
