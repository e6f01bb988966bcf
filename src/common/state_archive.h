// A checkpoint's in-memory form: named byte arrays, each the raw copy of a plain array or value
// (checkpoint/restart, docs/output.md "Checkpoints"). Every layer saves its state into one with
// the keys it chooses ("engine/x", "rigid/manifolds", ...) and reads it back the same way; only
// src/io turns an archive into HDF5 (io/checkpoint_file.h), so no layer needs HDF5.
//
// Values are copied as bytes (doubles, integers, Eigen fixed-size vectors and plain records of
// those, padding included): a checkpoint is read back by the same binary on the same kind of
// machine, which is what bit-identical continuation needs anyway. get() checks the key exists
// and that the byte count is a whole number of elements, and names the key when not.
#pragma once

#include <cstdint>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace hs {

class StateArchive {
 public:
  std::map<std::string, std::string> entries;

  bool has(const std::string& key) const { return entries.count(key) != 0; }

  template <class T>
  void put(const std::string& key, const std::vector<T>& v) {
    std::string& s = entries[key];
    s.resize(v.size() * sizeof(T));
    if (!v.empty()) std::memcpy(s.data(), static_cast<const void*>(v.data()), s.size());
  }
  template <class T>
  void put_value(const std::string& key, const T& v) {
    std::string& s = entries[key];
    s.resize(sizeof(T));
    std::memcpy(s.data(), static_cast<const void*>(&v), sizeof(T));
  }
  void put_bytes(const std::string& key, std::string bytes) { entries[key] = std::move(bytes); }

  template <class T>
  std::vector<T> get(const std::string& key) const {
    const std::string& s = at(key);
    if (s.size() % sizeof(T) != 0)
      throw std::runtime_error("checkpoint entry '" + key + "' has " + std::to_string(s.size()) +
                               " bytes, not a whole number of " + std::to_string(sizeof(T)) + "-byte records");
    std::vector<T> v(s.size() / sizeof(T));
    if (!v.empty()) std::memcpy(static_cast<void*>(v.data()), s.data(), s.size());
    return v;
  }
  template <class T>
  void get_into(const std::string& key, std::vector<T>& out) const {
    out = get<T>(key);
  }
  template <class T>
  T get_value(const std::string& key) const {
    const std::string& s = at(key);
    if (s.size() != sizeof(T))
      throw std::runtime_error("checkpoint entry '" + key + "' has " + std::to_string(s.size()) + " bytes, expected " +
                               std::to_string(sizeof(T)));
    T v;
    std::memcpy(static_cast<void*>(&v), s.data(), sizeof(T));
    return v;
  }
  const std::string& bytes(const std::string& key) const { return at(key); }

  /// One byte string: [count][key length, key, value length, value]... (for MPI gathers).
  std::string serialize() const {
    std::string out;
    auto put_u64 = [&](std::uint64_t n) { out.append(reinterpret_cast<const char*>(&n), sizeof n); };
    put_u64(entries.size());
    for (const auto& [k, v] : entries) {
      put_u64(k.size());
      out += k;
      put_u64(v.size());
      out += v;
    }
    return out;
  }
  /// Reads `size` bytes at `data` written by serialize(); returns the bytes consumed.
  std::size_t deserialize(const char* data, std::size_t size) {
    std::size_t o = 0;
    auto get_u64 = [&]() {
      if (o + 8 > size) throw std::runtime_error("checkpoint archive truncated");
      std::uint64_t n;
      std::memcpy(&n, data + o, 8);
      o += 8;
      return n;
    };
    entries.clear();
    const std::uint64_t count = get_u64();
    for (std::uint64_t e = 0; e < count; ++e) {
      const std::uint64_t kl = get_u64();
      if (o + kl > size) throw std::runtime_error("checkpoint archive truncated");
      std::string k(data + o, kl);
      o += kl;
      const std::uint64_t vl = get_u64();
      if (o + vl > size) throw std::runtime_error("checkpoint archive truncated");
      entries[k] = std::string(data + o, vl);
      o += vl;
    }
    return o;
  }

 private:
  const std::string& at(const std::string& key) const {
    auto it = entries.find(key);
    if (it == entries.end()) throw std::runtime_error("checkpoint has no entry '" + key + "'");
    return it->second;
  }
};

}  // namespace hs
