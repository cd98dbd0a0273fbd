#pragma once
// The one OpenMP reduction skeleton of the fits' point loops (the per-point factor / reduction split of
// small_gicp): every thread sums the terms of its share of the points 0..n-1 into its own partial accumulator
// (and its own scratch space, so a point's term allocates nothing); the caller then adds the partials in
// thread order, which keeps the sums deterministic for a given thread count. Internal to the core's .cpp
// files.

#include <Eigen/Core>
#include <vector>
#ifdef _OPENMP
#include <omp.h>
#endif

namespace s2m {

// reset(partial) prepares a thread's accumulator; point(j, scratch, partial) adds point j's terms.
template <class Scratch, class Partial, class ResetPartial, class PointTerm>
void AccumulateInParallel(Eigen::Index n, std::vector<Partial>& partials, const ResetPartial& reset,
                          const PointTerm& point) {
#ifdef _OPENMP
#pragma omp parallel
  {
#pragma omp single
    partials.resize(static_cast<std::size_t>(omp_get_num_threads()));
    Partial& mine = partials[static_cast<std::size_t>(omp_get_thread_num())];
    reset(mine);
    Scratch scratch;
#pragma omp for schedule(static)
    for (Eigen::Index j = 0; j < n; ++j) point(j, scratch, mine);
  }
#else
  partials.resize(1);
  reset(partials[0]);
  Scratch scratch;
  for (Eigen::Index j = 0; j < n; ++j) point(j, scratch, partials[0]);
#endif
}

}  // namespace s2m
