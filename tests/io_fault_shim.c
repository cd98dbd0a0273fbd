/* An LD_PRELOAD library that makes writes to chosen files fail the way a full disk or a failing device makes
 * them fail (docs/reliability.md, "Fault injection"). The tests in io_fault_test.cpp run the `scan2model`
 * command with it; nothing of the product links it.
 *
 * Environment:
 *   S2M_FAULT_PATH         writes to a file whose path contains this text are counted (unset: the shim is
 * idle) S2M_FAULT_AFTER_BYTES  the bytes such writes may put before every further one fails (default 0)
 *   S2M_FAULT_ERRNO        ENOSPC (a full disk, the default) or EIO (a device error)
 *   S2M_FAULT_FSYNC        1: the writes themselves succeed, and once the budget is spent fsync/fdatasync of
 *                          those files fail with EIO instead, as a device whose write-back fails reports it
 * Once the budget is spent the fault stays: a full disk does not free itself. A write that would cross the
 * budget fails whole (no short write), which every caller must handle anyway. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

static const char* fault_path = NULL;
static long long fault_budget = 0;
static int fault_errno = ENOSPC;
static int fault_fsync = 0;
static atomic_llong fault_written;
static atomic_int fault_active;

__attribute__((constructor)) static void FaultInit(void) {
  fault_path = getenv("S2M_FAULT_PATH");
  if (fault_path != NULL && fault_path[0] == '\0') fault_path = NULL;
  const char* after = getenv("S2M_FAULT_AFTER_BYTES");
  if (after != NULL) fault_budget = atoll(after);
  const char* code = getenv("S2M_FAULT_ERRNO");
  if (code != NULL && strcmp(code, "EIO") == 0) fault_errno = EIO;
  const char* sync = getenv("S2M_FAULT_FSYNC");
  fault_fsync = sync != NULL && strcmp(sync, "1") == 0;
}

/* Whether `fd` is open on a file whose path contains S2M_FAULT_PATH. */
static int FaultMatches(int fd) {
  if (fault_path == NULL || fd < 0) return 0;
  char link[64], path[4096];
  snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  const ssize_t n = readlink(link, path, sizeof path - 1);
  if (n <= 0) return 0;
  path[n] = '\0';
  return strstr(path, fault_path) != NULL;
}

/* Counts `count` bytes against the budget; returns 1 (errno set) when the write must fail. */
static int FaultCharge(int fd, size_t count) {
  if (!FaultMatches(fd)) return 0;
  if (atomic_load(&fault_active) && !fault_fsync) {
    errno = fault_errno;
    return 1;
  }
  const long long before = atomic_fetch_add(&fault_written, (long long)count);
  if (before + (long long)count > fault_budget) {
    atomic_store(&fault_active, 1);
    if (fault_fsync) return 0; /* the write lands in the cache; the sync will fail */
    errno = fault_errno;
    return 1;
  }
  return 0;
}

typedef ssize_t (*WriteFn)(int, const void*, size_t);
typedef ssize_t (*PwriteFn)(int, const void*, size_t, off_t);
typedef ssize_t (*Pwrite64Fn)(int, const void*, size_t, off64_t);
typedef ssize_t (*WritevFn)(int, const struct iovec*, int);
typedef int (*SyncFn)(int);

/* The C library's function the shim stands in front of, looked up once. */
#define FAULT_REAL(name, type) \
  static type real = NULL;     \
  if (real == NULL) real = (type)dlsym(RTLD_NEXT, name)

ssize_t write(int fd, const void* buffer, size_t count) {
  FAULT_REAL("write", WriteFn);
  if (FaultCharge(fd, count)) return -1;
  return real(fd, buffer, count);
}

ssize_t pwrite(int fd, const void* buffer, size_t count, off_t offset) {
  FAULT_REAL("pwrite", PwriteFn);
  if (FaultCharge(fd, count)) return -1;
  return real(fd, buffer, count, offset);
}

ssize_t pwrite64(int fd, const void* buffer, size_t count, off64_t offset) {
  FAULT_REAL("pwrite64", Pwrite64Fn);
  if (FaultCharge(fd, count)) return -1;
  return real(fd, buffer, count, offset);
}

ssize_t writev(int fd, const struct iovec* iov, int iovcnt) {
  FAULT_REAL("writev", WritevFn);
  size_t count = 0;
  for (int k = 0; k < iovcnt; ++k) count += iov[k].iov_len;
  if (FaultCharge(fd, count)) return -1;
  return real(fd, iov, iovcnt);
}

static int FaultSync(int fd) {
  if (fault_fsync && atomic_load(&fault_active) && FaultMatches(fd)) {
    errno = EIO;
    return 1;
  }
  return 0;
}

int fsync(int fd) {
  FAULT_REAL("fsync", SyncFn);
  if (FaultSync(fd)) return -1;
  return real(fd);
}

int fdatasync(int fd) {
  FAULT_REAL("fdatasync", SyncFn);
  if (FaultSync(fd)) return -1;
  return real(fd);
}
