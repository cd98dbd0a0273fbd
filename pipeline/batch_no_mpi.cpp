// scan2model built without MPI: `batch --mpi` explains how to get it.

#include <cstdlib>
#include <stdexcept>

#include "pipeline/batch_mpi.h"

namespace s2m::pipeline {

bool MpiBuilt() {
  return false;
}

bool LaunchedByMpi() {
  return std::getenv("OMPI_COMM_WORLD_SIZE") != nullptr || std::getenv("PMI_SIZE") != nullptr ||
         std::getenv("PMIX_RANK") != nullptr;
}

std::unique_ptr<MpiSession> StartMpi() {
  throw std::runtime_error(
      "this scan2model was built without MPI (install libopenmpi-dev and rebuild; docs/batch.md)");
}

}  // namespace s2m::pipeline
