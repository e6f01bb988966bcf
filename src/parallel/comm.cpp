#include "comm.h"

#include <mpi.h>

#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace hs::par {

namespace {

class SerialComm final : public Comm {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  void sum(double*, int) const override {}
  void sum(std::int64_t*, int) const override {}
  void max(double*, int) const override {}
  void sum_same_everywhere(double*, int) const override {}
  std::uint64_t exscan(std::uint64_t) const override { return 0; }
  std::string broadcast(const std::string& s, int) const override { return s; }
  void barrier() const override {}
  void exchange(const std::vector<int>& peers, const std::vector<Bytes>&, std::vector<Bytes>& recv) const override {
    if (!peers.empty()) throw std::logic_error("hs::par::serial: no peers in a serial run");
    recv.clear();
  }
  void exchange_sized(const std::vector<int>& peers, const std::vector<Bytes>&, std::vector<Bytes>&) const override {
    if (!peers.empty()) throw std::logic_error("hs::par::serial: no peers in a serial run");
  }
  std::vector<Bytes> all_to_all(const std::vector<Bytes>& send) const override { return send; }
  Bytes gather(const Bytes& mine, int) const override { return mine; }
  std::intptr_t native() const override { return 0; }
  [[noreturn]] void abort(int code) const override { std::exit(code); }
};

void check(int rc, const char* call) {
  if (rc != MPI_SUCCESS) throw std::runtime_error(std::string("MPI call failed: ") + call);
}

class MpiComm final : public Comm {
 public:
  explicit MpiComm(MPI_Comm c) : c_(c) {
    MPI_Comm_rank(c_, &rank_);
    MPI_Comm_size(c_, &size_);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  void sum(double* v, int n) const override {
    check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_SUM, c_), "MPI_Allreduce");
  }
  void sum(std::int64_t* v, int n) const override {
    check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_INT64_T, MPI_SUM, c_), "MPI_Allreduce");
  }
  void max(double* v, int n) const override {
    check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_MAX, c_), "MPI_Allreduce");
  }
  void sum_same_everywhere(double* v, int n) const override {
    if (rank_ == 0)
      check(MPI_Reduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_SUM, 0, c_), "MPI_Reduce");
    else
      check(MPI_Reduce(v, nullptr, n, MPI_DOUBLE, MPI_SUM, 0, c_), "MPI_Reduce");
    check(MPI_Bcast(v, n, MPI_DOUBLE, 0, c_), "MPI_Bcast");
  }
  std::uint64_t exscan(std::uint64_t v) const override {
    std::uint64_t out = 0;
    check(MPI_Exscan(&v, &out, 1, MPI_UINT64_T, MPI_SUM, c_), "MPI_Exscan");
    return rank_ == 0 ? 0 : out;
  }
  std::string broadcast(const std::string& s, int root) const override {
    std::uint64_t n = s.size();
    check(MPI_Bcast(&n, 1, MPI_UINT64_T, root, c_), "MPI_Bcast");
    std::string out = rank_ == root ? s : std::string(n, '\0');
    if (n) check(MPI_Bcast(out.data(), static_cast<int>(n), MPI_CHAR, root, c_), "MPI_Bcast");
    return out;
  }
  void barrier() const override { check(MPI_Barrier(c_), "MPI_Barrier"); }

  void exchange(const std::vector<int>& peers, const std::vector<Bytes>& send,
                std::vector<Bytes>& recv) const override {
    const std::size_t np = peers.size();
    recv.resize(np);
    std::vector<std::uint64_t> out_n(np), in_n(np);
    std::vector<MPI_Request> req(2 * np);
    for (std::size_t k = 0; k < np; ++k) {
      out_n[k] = send[k].size();
      check(MPI_Irecv(&in_n[k], 1, MPI_UINT64_T, peers[k], kTagSize, c_, &req[k]), "MPI_Irecv");
      check(MPI_Isend(&out_n[k], 1, MPI_UINT64_T, peers[k], kTagSize, c_, &req[np + k]), "MPI_Isend");
    }
    check(MPI_Waitall(static_cast<int>(2 * np), req.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
    int nreq = 0;
    for (std::size_t k = 0; k < np; ++k) {
      recv[k].resize(in_n[k]);
      if (in_n[k]) post(recv[k].data(), in_n[k], peers[k], true, req, nreq);
      if (out_n[k]) post(const_cast<char*>(send[k].data()), out_n[k], peers[k], false, req, nreq);
    }
    check(MPI_Waitall(nreq, req.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  }

  void exchange_sized(const std::vector<int>& peers, const std::vector<Bytes>& send,
                      std::vector<Bytes>& recv) const override {
    req_.clear();
    int nreq = 0;
    req_.resize(4 * peers.size() + 4);
    for (std::size_t k = 0; k < peers.size(); ++k) {
      if (!recv[k].empty()) post(recv[k].data(), recv[k].size(), peers[k], true, req_, nreq);
      if (!send[k].empty()) post(const_cast<char*>(send[k].data()), send[k].size(), peers[k], false, req_, nreq);
    }
    check(MPI_Waitall(nreq, req_.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  }

  std::vector<Bytes> all_to_all(const std::vector<Bytes>& send) const override {
    std::vector<int> peers;
    std::vector<Bytes> s, r;
    for (int p = 0; p < size_; ++p)
      if (p != rank_) {
        peers.push_back(p);
        s.push_back(send[p]);
      }
    exchange(peers, s, r);
    std::vector<Bytes> out(size_);
    out[rank_] = send[rank_];
    for (std::size_t k = 0; k < peers.size(); ++k) out[peers[k]] = std::move(r[k]);
    return out;
  }

  Bytes gather(const Bytes& mine, int root) const override {
    const int n = static_cast<int>(mine.size());
    std::vector<int> counts(size_), displ(size_);
    check(MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, root, c_), "MPI_Gather");
    Bytes out;
    if (rank_ == root) {
      int total = 0;
      for (int p = 0; p < size_; ++p) {
        displ[p] = total;
        total += counts[p];
      }
      out.resize(total);
    }
    check(MPI_Gatherv(mine.data(), n, MPI_CHAR, out.data(), counts.data(), displ.data(), MPI_CHAR, root, c_),
          "MPI_Gatherv");
    return out;
  }

  std::intptr_t native() const override { return reinterpret_cast<std::intptr_t>(c_); }
  [[noreturn]] void abort(int code) const override {
    MPI_Abort(c_, code);
    std::exit(code);
  }

 private:
  static constexpr int kTagSize = 101, kTagData = 102;
  static constexpr std::uint64_t kChunk = std::uint64_t{1} << 30;  // MPI counts are int

  void post(char* p, std::uint64_t n, int peer, bool receive, std::vector<MPI_Request>& req, int& nreq) const {
    for (std::uint64_t off = 0; off < n; off += kChunk) {
      const int len = static_cast<int>(std::min(kChunk, n - off));
      if (static_cast<std::size_t>(nreq) >= req.size()) req.resize(req.size() * 2 + 4);
      if (receive)
        check(MPI_Irecv(p + off, len, MPI_CHAR, peer, kTagData, c_, &req[nreq++]), "MPI_Irecv");
      else
        check(MPI_Isend(p + off, len, MPI_CHAR, peer, kTagData, c_, &req[nreq++]), "MPI_Isend");
    }
  }

  MPI_Comm c_;
  int rank_ = 0, size_ = 1;
  mutable std::vector<MPI_Request> req_;
};

}  // namespace

const Comm& serial() {
  static const SerialComm s;
  return s;
}

bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE", "MPI_LOCALNRANKS"})
    if (std::getenv(v) != nullptr) return true;
  return false;
}

Session::Session(int* argc, char*** argv) : mpi_(launched_by_mpi()) {
  if (!mpi_) {
    world_ = std::make_unique<SerialComm>();
    return;
  }
  // Ghost updates are one message of tens to hundreds of KB per neighbour and step. Open MPI's
  // shared-memory transport sends those through a kernel single copy (CMA, process_vm_readv),
  // one system call per message; copying through its shared buffers instead made the 2-rank
  // granular benchmark ~6 % faster (docs/parallel.md "Transport"). Not when the user's
  // environment sets it, under this name or Open MPI 5's (btl sm); a value set only in an
  // mca-params.conf file loses to this one.
  if (std::getenv("OMPI_MCA_btl_vader_single_copy_mechanism") == nullptr &&
      std::getenv("OMPI_MCA_btl_sm_single_copy_mechanism") == nullptr)
    setenv("OMPI_MCA_btl_vader_single_copy_mechanism", "none", 0);
  int provided = 0;
  check(MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  world_ = std::make_unique<MpiComm>(MPI_COMM_WORLD);
}

Session::~Session() {
  if (!mpi_) return;
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

void Session::abort(int code) const {
  if (mpi_) MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

}  // namespace hs::par
