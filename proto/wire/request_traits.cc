// Lenient request parsing (see request_traits.h).
#include "request_traits.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/unknown_field_set.h>

#include <cstdint>
#include <map>

#include "activefoam/utf8.h"

namespace activefoam::wire {
namespace {

// The largest field number protobuf allows: never one of ours.
constexpr int kErrorField = 536870911;

bool readVarint(const std::string& b, std::size_t& at, std::size_t end, std::uint64_t& v) {
  v = 0;
  for (int shift = 0; shift < 64 && at < end; shift += 7) {
    const auto byte = static_cast<unsigned char>(b[at++]);
    v |= static_cast<std::uint64_t>(byte & 0x7F) << shift;
    if (!(byte & 0x80)) return true;
  }
  return false;
}

// Walks the wire form of a `d` message in b[at, end); replaces the bytes of string fields that
// are not UTF-8 by '?' and names the first such field in `first` (a path: "spec.cells.x",
// "settings[2]"). False when the bytes are not a well-formed message.
bool repairStrings(std::string& b, std::size_t at, std::size_t end,
                   const google::protobuf::Descriptor* d, const std::string& prefix,
                   std::string& first) {
  std::map<int, int> seen;  // field number → occurrences, for the index of repeated fields
  while (at < end) {
    std::uint64_t tag = 0;
    if (!readVarint(b, at, end, tag)) return false;
    const int number = static_cast<int>(tag >> 3);
    const auto wire = static_cast<int>(tag & 7);
    std::uint64_t len = 0;
    switch (wire) {
      case 0:
        if (!readVarint(b, at, end, len)) return false;
        continue;
      case 1:
        at += 8;
        continue;
      case 5:
        at += 4;
        continue;
      case 2:
        if (!readVarint(b, at, end, len) || len > end - at) return false;
        break;
      default:
        return false;  // groups (3, 4) are not ours; 6, 7 are not wire types
    }
    const google::protobuf::FieldDescriptor* f = d ? d->FindFieldByNumber(number) : nullptr;
    const int index = seen[number]++;
    if (f) {
      std::string name = prefix + f->name();
      if (f->is_repeated()) name += '[' + std::to_string(index) + ']';
      if (f->type() == google::protobuf::FieldDescriptor::TYPE_STRING) {
        const std::size_t n = static_cast<std::size_t>(len);
        for (std::size_t bad;
             (bad = invalidUtf8At(std::string_view(b).substr(at, n))) != std::string::npos;) {
          if (first.empty()) first = name + ": not valid UTF-8 (byte " + std::to_string(bad) + ")";
          b[at + bad] = '?';
        }
      } else if (f->type() == google::protobuf::FieldDescriptor::TYPE_MESSAGE) {
        if (!repairStrings(b, at, at + static_cast<std::size_t>(len), f->message_type(), name + ".",
                           first))
          return false;
      }
    }
    at += static_cast<std::size_t>(len);
  }
  return at == end;
}

}  // namespace

void lenientParse(std::string bytes, google::protobuf::Message& msg) {
  msg.Clear();
  // The common case costs one scan: a clean request is parsed as protobuf would.
  std::string why;
  const bool parsed = repairStrings(bytes, 0, bytes.size(), msg.GetDescriptor(), "", why) &&
                      msg.ParseFromString(bytes);
  if (parsed && why.empty()) return;
  if (!parsed) {
    msg.Clear();
    why = "malformed request: " + std::to_string(bytes.size()) + " bytes that are not a " +
          msg.GetDescriptor()->full_name() + " message";
  }
  msg.GetReflection()->MutableUnknownFields(&msg)->AddLengthDelimited(kErrorField, why);
}

std::string requestError(const google::protobuf::Message& msg) {
  const google::protobuf::UnknownFieldSet& u = msg.GetReflection()->GetUnknownFields(msg);
  for (int k = 0; k < u.field_count(); ++k)
    if (u.field(k).number() == kErrorField &&
        u.field(k).type() == google::protobuf::UnknownField::TYPE_LENGTH_DELIMITED)
      return u.field(k).length_delimited();
  return "";
}

}  // namespace activefoam::wire
