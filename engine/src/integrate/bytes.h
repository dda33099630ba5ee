// Little-endian byte strings of PODs, vectors and matrices: checkpoints and the spheroid cache.
// Readers throw std::invalid_argument("<what>: truncated") on short input.
#pragma once

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include <Eigen/Core>

namespace activefoam::bytes {

class Writer {
 public:
  template <typename T>
  void pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  template <typename T>
  void vec(const std::vector<T>& v) {
    pod<std::uint64_t>(v.size());
    out_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void str(const std::string& s) {
    pod<std::uint64_t>(s.size());
    out_ += s;
  }
  void mat(const Eigen::Matrix3Xd& m) {
    pod<std::uint64_t>(static_cast<std::uint64_t>(m.cols()));
    out_.append(reinterpret_cast<const char*>(m.data()), sizeof(double) * m.size());
  }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
};

class Reader {
 public:
  Reader(std::string&&, const char* = nullptr) = delete;  // keeps a reference: no temporaries
  Reader(const std::string& in, const char* what = "checkpoint") : in_(in), what_(what) {}
  template <typename T>
  T pod() {
    T v;
    need(sizeof v);
    std::memcpy(&v, in_.data() + pos_, sizeof v);
    pos_ += sizeof v;
    return v;
  }
  template <typename T>
  std::vector<T> vec() {
    const auto n = count(sizeof(T));
    std::vector<T> v(n);
    std::memcpy(static_cast<void*>(v.data()), in_.data() + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
    return v;
  }
  std::string str() {
    const auto n = count(1);
    std::string s = in_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  Eigen::Matrix3Xd mat() {
    const auto n = count(3 * sizeof(double));
    Eigen::Matrix3Xd m(3, static_cast<Eigen::Index>(n));
    std::memcpy(m.data(), in_.data() + pos_, 3 * n * sizeof(double));
    pos_ += 3 * n * sizeof(double);
    return m;
  }
  bool done() const { return pos_ == in_.size(); }

 private:
  std::size_t count(std::size_t elem) {
    const auto n = pod<std::uint64_t>();
    if (n > (in_.size() - pos_) / elem)
      throw std::invalid_argument(std::string(what_) + ": truncated");
    return static_cast<std::size_t>(n);
  }
  void need(std::size_t n) const {
    if (in_.size() - pos_ < n) throw std::invalid_argument(std::string(what_) + ": truncated");
  }
  const std::string& in_;
  const char* what_;
  std::size_t pos_ = 0;
};

}  // namespace activefoam::bytes
