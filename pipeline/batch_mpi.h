#pragma once
// MPI for `scan2model batch` (docs/batch.md), behind a small interface so that only apps/batch_mpi.cpp sees
// <mpi.h>; without MPI at build time apps/batch_no_mpi.cpp provides a single process.

#include <memory>
#include <string>
#include <vector>

namespace s2m::pipeline {

class MpiSession {
 public:
  virtual ~MpiSession() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  // Ranks on this machine (for the default number of threads per rank).
  virtual int local_size() const = 0;
  // Every rank's text, in rank order, on rank 0 (empty elsewhere).
  virtual std::vector<std::string> GatherToRoot(const std::string& mine) = 0;
  // Rank 0's value on every rank.
  virtual int Broadcast(int value) = 0;
};

// True when scan2model was built with MPI.
bool MpiBuilt();
// True when the process was started by an MPI launcher (mpirun sets OMPI_COMM_WORLD_SIZE, PMI_SIZE or
// PMIX_RANK).
bool LaunchedByMpi();
// Initializes MPI (finalized when the session is destroyed). Throws std::runtime_error when not built with
// MPI.
std::unique_ptr<MpiSession> StartMpi();

}  // namespace s2m::pipeline
