#pragma once
// DDS domain ids for tests that may run at the same time (ctest -j, two checkouts on one machine).
// Each test process takes domains that no other process on the machine holds, by an exclusive
// lock on /tmp/mav-test-dds-domain-<id>.lock that stays held until the process exits; a domain
// derived from the pid alone collides whenever two tests' pids differ by the wrong amount.
// Ids 1..199 (protos_test keeps 200..229 to itself). Child processes get the id by flag.

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <string>

namespace mav::test_support {

// The same `key` returns the same domain within a process; different keys get different domains.
inline int64_t TestDomain(int key) {
  static std::mutex mutex;
  static std::map<int, int64_t> taken;
  constexpr int64_t kDomains = 199;
  std::lock_guard<std::mutex> lock(mutex);
  if (const auto it = taken.find(key); it != taken.end()) return it->second;
  const int64_t start = (static_cast<int64_t>(::getpid()) * 7919 + key * 31) % kDomains;
  for (int64_t i = 0; i < kDomains; ++i) {
    const int64_t domain = 1 + (start + i) % kDomains;
    bool mine = false;
    for (const auto& entry : taken) mine |= entry.second == domain;
    if (mine) continue;
    const std::string path = "/tmp/mav-test-dds-domain-" + std::to_string(domain) + ".lock";
    const int fd = ::open(path.c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      taken[key] = domain;  // fd stays open: the lock is held until the process exits
      return domain;
    }
    ::close(fd);
  }
  return 1 + start;  // every domain busy: run anyway, foreign traffic may then show up
}

}  // namespace mav::test_support
