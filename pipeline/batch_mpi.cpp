// The only file that includes <mpi.h> (docs/batch.md): MPI_Init_thread (FUNNELED: only the main thread calls
// MPI; the worker threads of each rank fit objects), MPI_Gatherv of each rank's summary entries to rank 0.

#include "pipeline/batch_mpi.h"

#include <mpi.h>

#include <cstdlib>
#include <numeric>
#include <stdexcept>

namespace s2m::pipeline {
namespace {

class OpenMpiSession final : public MpiSession {
 public:
  OpenMpiSession() {
    int provided = 0;
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
      throw std::runtime_error("MPI_Init_thread failed");
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
    MPI_Comm local;
    MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &local);
    MPI_Comm_size(local, &local_size_);
    MPI_Comm_free(&local);
  }
  ~OpenMpiSession() override { MPI_Finalize(); }
  OpenMpiSession(const OpenMpiSession&) = delete;
  OpenMpiSession& operator=(const OpenMpiSession&) = delete;

  int rank() const override { return rank_; }
  int size() const override { return size_; }
  int local_size() const override { return local_size_; }

  std::vector<std::string> GatherToRoot(const std::string& mine) override {
    int length = static_cast<int>(mine.size());
    std::vector<int> lengths(static_cast<std::size_t>(size_));
    MPI_Gather(&length, 1, MPI_INT, lengths.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
    std::vector<int> offsets(static_cast<std::size_t>(size_), 0);
    std::vector<char> all;
    if (rank_ == 0) {
      std::exclusive_scan(lengths.begin(), lengths.end(), offsets.begin(), 0);
      all.resize(static_cast<std::size_t>(offsets.back() + lengths.back()));
    }
    MPI_Gatherv(mine.data(), length, MPI_CHAR, all.data(), lengths.data(), offsets.data(), MPI_CHAR, 0,
                MPI_COMM_WORLD);
    std::vector<std::string> out;
    if (rank_ == 0) {
      for (std::size_t r = 0; r < lengths.size(); ++r)
        out.emplace_back(all.data() + offsets[r], static_cast<std::size_t>(lengths[r]));
    }
    return out;
  }

  int Broadcast(int value) override {
    MPI_Bcast(&value, 1, MPI_INT, 0, MPI_COMM_WORLD);
    return value;
  }

 private:
  int rank_ = 0, size_ = 1, local_size_ = 1;
};

}  // namespace

bool MpiBuilt() {
  return true;
}

bool LaunchedByMpi() {
  return std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMI_SIZE") != nullptr ||
         std::getenv("PMIX_RANK") != nullptr;
}

std::unique_ptr<MpiSession> StartMpi() {
  return std::make_unique<OpenMpiSession>();
}

}  // namespace s2m::pipeline
