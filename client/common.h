// What more than one foam subcommand uses: the connection to foamd, the exit codes, and the
// helpers that several commands (commands/) call. A helper that one command uses stays in that
// command's file.
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <google/protobuf/message.h>

#include "activefoam/v1/service.grpc.pb.h"

namespace activefoam::client {

// The exit codes of main.cc's header comment.
inline constexpr int kOk = 0, kJobNotOk = 1, kUsage = 2, kRpc = 3, kAuth = 4, kNotFound = 5;

struct Conn {
  std::string server = "127.0.0.1:50051";
  std::string token;
  std::string tls_ca;  // PEM roots; non-empty: connect with TLS
  std::unique_ptr<v1::Foam::Stub> stub;

  bool loopback() const;
  void connect();
  std::unique_ptr<grpc::ClientContext> ctx(double deadline_s = 30) const;
};

// Prints the failed call on stderr; returns the exit code for its status.
int rpcError(const grpc::Status& s, const std::string& what);

std::string stateName(v1::JobState s);

std::string readFile(const std::string& path);

std::string toJsonText(const google::protobuf::Message& m);

// Follows a job's events to its end, reconnecting (from the last sequence number seen) when the
// stream breaks. Progress on stderr. Returns the final job, or nullopt on a non-retryable error.
std::optional<v1::Job> watch(Conn& conn, const std::string& id, bool quiet, int& rc);

int jobExit(const v1::Job& j);

// ---- the spec of foam submit and foam sweep -------------------------------------------------

inline constexpr const char* kPresetHelp =
    "fidelity preset: standard (the default) | reference (docs/science/presets.md); "
    "--set numerics.* keys win over it";
inline constexpr const char* kAccuracyHelp =
    "accuracy target instead of numerics, e.g. --accuracy contact_angle_deg=2 or "
    "trajectory_deg=5: foamd runs the cheapest preset that promises it (repeatable)";

struct SpecOptions {
  std::string file;  // SPEC; "-" = stdin
  std::string scene;
  std::vector<std::string> settings;  // --set
  std::string preset;
  std::vector<std::string> accuracy;
};

// The spec file's text, "" without one. Throws std::runtime_error when it cannot be read or is not
// UTF-8.
std::string specText(const std::string& spec_file);

// The settings a request carries: the scene, then --accuracy and --preset, then --set.
std::vector<std::string> specSettings(const SpecOptions& o);

// ---- list and results -----------------------------------------------------------------------

inline constexpr const char* kOutcomeHelp = "fusion outcome: fused|arrested|separated|no-contact";

}  // namespace activefoam::client
