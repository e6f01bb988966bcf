// The one door to MPI. A Comm is either the serial communicator (one rank; no MPI call is ever
// made, so a plain `hybridsim scene.json` never initialises MPI) or MPI_COMM_WORLD of a run
// started under mpirun. Everything the engine needs from MPI goes through these few calls:
// reductions, a prefix sum, a broadcast, and byte-buffer exchanges between peer ranks.
//
// Determinism: reductions use MPI's fixed reduction order for a given rank count and message
// sizes (Open MPI's default for MPI_Allreduce is deterministic for a fixed communicator size),
// and exchanges are unpacked in ascending peer order, so the same scene, binary and rank count
// give the same answer.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hs::par {

using Bytes = std::vector<char>;

class Comm {
 public:
  virtual ~Comm() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  bool parallel() const { return size() > 1; }

  virtual void sum(double* v, int n) const = 0;
  virtual void sum(std::int64_t* v, int n) const = 0;
  virtual void max(double* v, int n) const = 0;
  /// Sum reduced on rank 0 and broadcast: bit-identical on every rank by construction (for
  /// state that replicated copies must agree on exactly, e.g. impulses on rigid blocks).
  virtual void sum_same_everywhere(double* v, int n) const = 0;
  double sum(double v) const { sum(&v, 1); return v; }
  std::int64_t sum(std::int64_t v) const { sum(&v, 1); return v; }
  double max(double v) const { max(&v, 1); return v; }
  /// Exclusive prefix sum over ranks (rank 0 gets 0).
  virtual std::uint64_t exscan(std::uint64_t v) const = 0;
  /// Rank `root`'s string on every rank.
  virtual std::string broadcast(const std::string& s, int root = 0) const = 0;
  virtual void barrier() const = 0;
  /// Point-to-point exchange with `peers` (symmetric: if a is b's peer, b is a's): send[k] goes to
  /// peers[k], recv[k] comes from peers[k]. Message sizes need not be known in advance.
  virtual void exchange(const std::vector<int>& peers, const std::vector<Bytes>& send,
                        std::vector<Bytes>& recv) const = 0;
  /// The same with sizes known on both sides (ghost updates): recv[k] must already have the size
  /// peers[k] sends. One round of messages instead of two.
  virtual void exchange_sized(const std::vector<int>& peers, const std::vector<Bytes>& send,
                              std::vector<Bytes>& recv) const = 0;
  /// All-to-all: send[r] goes to rank r; returns what every rank sent to this one (index = source).
  virtual std::vector<Bytes> all_to_all(const std::vector<Bytes>& send) const = 0;
  /// Concatenation of every rank's bytes, on rank `root` only (others get {}).
  virtual Bytes gather(const Bytes& mine, int root = 0) const = 0;
  /// Ends every rank at once (MPI_Abort; std::exit when serial): for an error that struck one
  /// rank only, which the others would otherwise wait for in their next collective forever.
  [[noreturn]] virtual void abort(int code) const = 0;
  /// Native MPI_Comm handle (as a pointer-sized integer) for HDF5's MPI-IO driver; 0 when serial.
  virtual std::intptr_t native() const = 0;
};

/// The serial communicator: one rank, no MPI.
const Comm& serial();

/// Owns MPI for the life of the process when the program was started by mpirun/mpiexec (detected
/// from the launcher's environment), else stays serial. Construct once, at the top of main().
class Session {
 public:
  Session(int* argc, char*** argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  const Comm& world() const { return *world_; }
  /// True when started by an MPI launcher (even with one rank).
  bool mpi() const { return mpi_; }
  /// Aborts every rank (after an error on one rank that the others cannot see).
  [[noreturn]] void abort(int code) const;

 private:
  bool mpi_ = false;
  std::unique_ptr<Comm> world_;
};

/// True when the environment says this process was started by an MPI launcher.
bool launched_by_mpi();

}  // namespace hs::par
