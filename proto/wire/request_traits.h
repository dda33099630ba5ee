// How foamd's requests come off the wire. Force-included (`-include`) into every translation
// unit that uses activefoam_proto, so that all of them see the same SerializationTraits.
//
// protobuf refuses to parse a proto3 string field that is not UTF-8, and gRPC's callback server
// answers a request it cannot parse with UNIMPLEMENTED and no message. So requests are parsed
// leniently instead: a string that is not UTF-8 has its offending bytes replaced by '?' (the
// lengths stay, so the rest parses as sent) and a message that cannot be parsed at all arrives
// empty; either way the request carries the reason in an unknown field, which the service turns
// into INVALID_ARGUMENT naming the field (`requestError`).
#pragma once

#include <grpcpp/impl/codegen/proto_utils.h>
#include <grpcpp/support/byte_buffer.h>

#include <string>

#include "activefoam/v1/service.pb.h"

namespace activefoam::wire {

// Parses `bytes` into `msg` as described above.
void lenientParse(std::string bytes, google::protobuf::Message& msg);

// Why the request could not be taken as sent ("tag: not valid UTF-8 (byte 3)", "malformed
// request: ..."); empty when it parsed cleanly.
std::string requestError(const google::protobuf::Message& msg);

}  // namespace activefoam::wire

#define ACTIVEFOAM_LENIENT_REQUEST(T)                                         \
  namespace grpc {                                                            \
  template <>                                                                 \
  class SerializationTraits<T, void> {                                        \
   public:                                                                    \
    static Status Serialize(const T& msg, ByteBuffer* bb, bool* own_buffer) { \
      return GenericSerialize<ProtoBufferWriter, T>(msg, bb, own_buffer);     \
    }                                                                         \
    static Status Deserialize(ByteBuffer* buffer, T* msg) {                   \
      std::string bytes;                                                      \
      if (buffer->Valid()) {                                                  \
        std::vector<Slice> slices;                                            \
        (void)buffer->Dump(&slices);                                          \
        for (const Slice& s : slices)                                         \
          bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());   \
      }                                                                       \
      buffer->Clear();                                                        \
      activefoam::wire::lenientParse(std::move(bytes), *msg);                 \
      return Status::OK;                                                      \
    }                                                                         \
  };                                                                          \
  }

ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::SubmitJobRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::GetJobRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::ListJobsRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::CancelJobRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::WatchJobRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::GetResultsRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::QueryResultsRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::SubmitSweepRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::GetSnapshotRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::ReportTaskRequest)
ACTIVEFOAM_LENIENT_REQUEST(activefoam::v1::ResolveSpecRequest)
