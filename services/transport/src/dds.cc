#include "mav/transport/dds.h"

#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include <dds/ddsc/dds_loan_api.h>

#include "mav/common/log.h"
#include "mav/common/parse.h"

namespace mav::transport {

namespace {

// Keep in sync with deploy/cyclonedds.xml (that file explains each setting).
constexpr char kLoopbackDdsConfig[] =
    "<CycloneDDS xmlns=\"https://cdds.io/config\"><Domain id=\"any\">"
    "<General>"
    "<Interfaces><NetworkInterface name=\"lo\" multicast=\"false\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast>"
    "<MaxMessageSize>65500B</MaxMessageSize>"
    "<FragmentSize>64000B</FragmentSize>"
    "</General>"
    "<Discovery>"
    "<ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex>"
    "<Peers><Peer address=\"127.0.0.1\"/></Peers>"
    "</Discovery>"
    "<Internal>"
    "<SocketReceiveBufferSize min=\"default\" max=\"4MiB\"/>"
    "<SocketSendBufferSize min=\"default\" max=\"4MiB\"/>"
    "<HeartbeatInterval>5ms</HeartbeatInterval>"
    "<Watermarks><WhcHigh>4MiB</WhcHigh></Watermarks>"
    "</Internal>"
    "</Domain></CycloneDDS>";

// Appended to the configuration by DdsOptions::shared_memory. Warnings only: iceoryx's info
// lines go to standard output, one per reader and writer.
constexpr char kSharedMemoryConfig[] =
    "<CycloneDDS xmlns=\"https://cdds.io/config\"><Domain id=\"any\">"
    "<SharedMemory><Enable>true</Enable><LogLevel>warn</LogLevel></SharedMemory>"
    "</Domain></CycloneDDS>";

constexpr int64_t kMaxDomainId = 230;

// The files of a DDS Security identity directory (deploy/dds-security/make-certs.sh) and the
// Cyclone configuration elements that name them, by plugin.
struct SecurityFile {
  const char* group;
  const char* element;
  const char* file;
};
constexpr SecurityFile kSecurityFiles[] = {
    {"Authentication", "IdentityCA", "identity_ca.pem"},
    {"Authentication", "IdentityCertificate", "cert.pem"},
    {"Authentication", "PrivateKey", "key.pem"},
    {"AccessControl", "PermissionsCA", "permissions_ca.pem"},
    {"AccessControl", "Governance", "governance.p7s"},
    {"AccessControl", "Permissions", "permissions.p7s"},
};  // 7400 + 250 * id + offsets must stay below 65536

}  // namespace

Status DdsStatus(dds_return_t ret, const std::string& what) {
  if (ret >= 0) return Status::Ok();
  const std::string message = what + ": " + dds_strretcode(ret);
  switch (ret) {
    case DDS_RETCODE_BAD_PARAMETER:
    case DDS_RETCODE_INCONSISTENT_POLICY:
    case DDS_RETCODE_IMMUTABLE_POLICY:
      return Status::InvalidArgument(message);
    case DDS_RETCODE_PRECONDITION_NOT_MET:
    case DDS_RETCODE_NOT_ENABLED:
    case DDS_RETCODE_ILLEGAL_OPERATION:
      return Status::FailedPrecondition(message);
    case DDS_RETCODE_NOT_ALLOWED_BY_SECURITY:
      return Status::FailedPrecondition(
          message + " (the permissions of this DDS Security identity do not grant it)");
    case DDS_RETCODE_TIMEOUT:
    case DDS_RETCODE_OUT_OF_RESOURCES:
    case DDS_RETCODE_ALREADY_DELETED:
      return Status::Unavailable(message);
    default:
      return Status::Internal(message);
  }
}

const char* LoopbackDdsConfig() { return kLoopbackDdsConfig; }
const char* SharedMemoryConfig() { return kSharedMemoryConfig; }

bool DdsOptions::IsValid(std::string* why) const {
  if (domain < 0 || domain > kMaxDomainId) {
    if (why != nullptr) {
      *why = "dds domain: " + std::to_string(domain) + " is outside [0, " +
             std::to_string(kMaxDomainId) + "]";
    }
    return false;
  }
  if (shared_memory && !security_dir.empty()) {
    if (why != nullptr) {
      *why =
          "dds shared memory (--dds-shm, MAV_DDS_SHM) and DDS Security (--dds-security, "
          "MAV_DDS_SECURITY) cannot be combined: samples in shared memory bypass the "
          "security plugins' encryption and access control";
    }
    return false;
  }
  return true;
}

bool Entity::UsesSharedMemory() const {
  return handle_ > 0 && dds_is_shared_memory_available(handle_);
}

Status CheckRoudi(const std::string& socket_path) {
  const std::string how =
      " (DDS shared memory is on: start iceoryx's RouDi first, e.g. "
      "`iox-roudi -c deploy/roudi.toml &`, Debian package iceoryx; or "
      "turn --dds-shm / MAV_DDS_SHM off)";
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  if (socket_path.empty() || socket_path.size() >= sizeof(address.sun_path)) {
    return Status::InvalidArgument("RouDi socket path '" + socket_path + "': empty or too long");
  }
  std::memcpy(address.sun_path, socket_path.c_str(), socket_path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return Status::Unavailable(std::string("socket(AF_UNIX): ") + std::strerror(errno));
  // A datagram socket's connect() succeeds only while a process has the path bound: a socket
  // file left behind by a RouDi that died gives ECONNREFUSED.
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address));
  const int error = errno;
  ::close(fd);
  if (rc == 0) return Status::Ok();
  return Status::Unavailable("iceoryx RouDi does not answer at " + socket_path + ": " +
                             std::strerror(error) + how);
}

std::string DdsOptions::ResolvedConfig() const {
  std::string base;
  if (!config.empty()) {
    base = config.front() == '<' || config.rfind("file://", 0) == 0 ? config : "file://" + config;
  } else if (const char* uri = std::getenv("CYCLONEDDS_URI"); uri != nullptr && *uri != '\0') {
    base = uri;
  } else {
    base = kLoopbackDdsConfig;
  }
  // Cyclone reads a comma-separated list of files and XML fragments, later ones adding to (and
  // overriding) earlier ones.
  if (!security_dir.empty()) base.append(",").append(SecurityConfig(security_dir));
  if (shared_memory) base.append(",").append(kSharedMemoryConfig);
  return base;
}

std::string SecurityConfig(const std::string& dir) {
  // No <Library> elements: Cyclone's default plugin names (dds_security_auth, _ac, _crypto)
  // with their init/finalize functions, which Debian's libddsc finds in its own plugin
  // directory (/usr/lib/<arch>/libddsc0debian) whatever the architecture.
  std::string out = "<CycloneDDS xmlns=\"https://cdds.io/config\"><Domain id=\"any\"><Security>";
  const char* group = nullptr;
  for (const SecurityFile& f : kSecurityFiles) {
    if (group == nullptr || std::strcmp(group, f.group) != 0) {
      if (group != nullptr) out.append("</").append(group).append(">");
      group = f.group;
      out.append("<").append(group).append(">");
    }
    out.append("<").append(f.element).append(">file://").append(dir).append("/").append(f.file);
    out.append("</").append(f.element).append(">");
  }
  return out.append("</").append(group).append("></Security></Domain></CycloneDDS>");
}

Result<std::string> CheckSecurityDir(const std::string& dir, const std::string& what) {
  if (dir.empty()) return Status::InvalidArgument(what + ": empty directory");
  std::error_code error;
  const std::filesystem::path absolute = std::filesystem::absolute(dir, error);
  if (error) return Status::InvalidArgument(what + ": " + dir + ": " + error.message());
  std::string path = absolute.lexically_normal().string();
  while (path.size() > 1 && path.back() == '/') path.pop_back();
  if (path.find_first_of(",\"'<>&") != std::string::npos) {
    return Status::InvalidArgument(what + ": " + path +
                                   ": a comma, quote, '<', '>' or '&' in the path cannot go into "
                                   "Cyclone's configuration; move the directory");
  }
  if (!std::filesystem::is_directory(path, error)) {
    return Status::InvalidArgument(what + ": " + path +
                                   ": not a directory (make one with deploy/dds-security/"
                                   "make-certs.sh OUT; give OUT/<program>)");
  }
  for (const SecurityFile& f : kSecurityFiles) {
    const std::string file = path + "/" + f.file;
    if (::access(file.c_str(), R_OK) != 0) {
      std::string names;
      for (const SecurityFile& g : kSecurityFiles)
        names += (names.empty() ? "" : ", ") + std::string(g.file);
      return Status::InvalidArgument(what + ": " + file + ": " + std::strerror(errno) +
                                     " (an identity directory of deploy/dds-security/"
                                     "make-certs.sh has " +
                                     names + ")");
    }
  }
  return path;
}

void AddDdsFlags(FlagParser* flags, DdsOptions* options) {
  flags->AddInt("dds-domain", &options->domain, "DDS domain id, 0..230 (env MAV_DDS_DOMAIN)");
  flags->AddString("dds-config", &options->config,
                   "Cyclone DDS config: XML, file://PATH or PATH (default: env CYCLONEDDS_URI, "
                   "else the built-in loopback config = deploy/cyclonedds.xml)");
  flags->AddString("dds-security", &options->security_dir,
                   "DDS Security identity directory, OUT/<program> of "
                   "deploy/dds-security/make-certs.sh (env MAV_DDS_SECURITY; default: none, "
                   "the data plane unauthenticated)");
  flags->AddBool("dds-shm", &options->shared_memory,
                 "carry samples between processes on this machine in shared memory (Cyclone's "
                 "iceoryx transport; needs iox-roudi running; env MAV_DDS_SHM=1)");
}

Status ApplyDdsEnv(const FlagParser& flags, DdsOptions* options) {
  if (!flags.WasSet("dds-domain")) {
    if (const char* text = std::getenv("MAV_DDS_DOMAIN"); text != nullptr && *text != '\0') {
      MAV_ASSIGN_OR_RETURN(options->domain,
                           ParseInt64(text, "environment variable MAV_DDS_DOMAIN"));
    }
  }
  std::string what = "--dds-security";
  if (!flags.WasSet("dds-security")) {
    if (const char* dir = std::getenv("MAV_DDS_SECURITY"); dir != nullptr && *dir != '\0') {
      options->security_dir = dir;
      what = "environment variable MAV_DDS_SECURITY";
    }
  }
  if (!options->security_dir.empty()) {
    MAV_ASSIGN_OR_RETURN(options->security_dir, CheckSecurityDir(options->security_dir, what));
  }
  if (!flags.WasSet("dds-shm")) {
    if (const char* text = std::getenv("MAV_DDS_SHM"); text != nullptr && *text != '\0') {
      const std::string value = text;
      if (value != "0" && value != "1") {
        return Status::InvalidArgument("environment variable MAV_DDS_SHM: '" + value +
                                       "' is neither 0 nor 1");
      }
      options->shared_memory = value == "1";
    }
  }
  std::string why;
  if (!options->IsValid(&why)) return Status::InvalidArgument(why);
  return Status::Ok();
}

// ---- Qos --------------------------------------------------------------------------------------

Qos::Qos() : qos_(dds_create_qos()) {}
Qos::~Qos() {
  if (qos_ != nullptr) dds_delete_qos(qos_);
}
Qos::Qos(Qos&& other) noexcept : qos_(std::exchange(other.qos_, nullptr)) {}
Qos& Qos::operator=(Qos&& other) noexcept {
  if (this != &other) {
    if (qos_ != nullptr) dds_delete_qos(qos_);
    qos_ = std::exchange(other.qos_, nullptr);
  }
  return *this;
}
Qos& Qos::Reliable(int64_t max_blocking_ns) {
  dds_qset_reliability(qos_, DDS_RELIABILITY_RELIABLE, max_blocking_ns);
  return *this;
}
Qos& Qos::BestEffort() {
  dds_qset_reliability(qos_, DDS_RELIABILITY_BEST_EFFORT, 0);
  return *this;
}
Qos& Qos::KeepLast(int32_t depth) {
  dds_qset_history(qos_, DDS_HISTORY_KEEP_LAST, depth);
  return *this;
}
Qos& Qos::KeepAll() {
  dds_qset_history(qos_, DDS_HISTORY_KEEP_ALL, DDS_LENGTH_UNLIMITED);
  return *this;
}
Qos& Qos::Volatile() {
  dds_qset_durability(qos_, DDS_DURABILITY_VOLATILE);
  return *this;
}
Qos& Qos::TransientLocal() {
  dds_qset_durability(qos_, DDS_DURABILITY_TRANSIENT_LOCAL);
  return *this;
}
Qos& Qos::Liveliness(int64_t lease_ns) {
  dds_qset_liveliness(qos_, DDS_LIVELINESS_AUTOMATIC, lease_ns);
  return *this;
}
Qos Qos::SensorStream() {
  Qos qos;
  qos.Reliable(DDS_SECS(1)).KeepLast(4).Volatile();
  return qos;
}
Qos Qos::HighRate() {
  Qos qos;
  qos.Reliable(DDS_SECS(1)).KeepLast(400).Volatile();
  return qos;
}
Qos Qos::State() {
  Qos qos;
  qos.Reliable(DDS_SECS(1)).KeepLast(400).Volatile();
  return qos;
}
Qos Qos::Command() {
  Qos qos;
  qos.Reliable(DDS_SECS(1)).KeepLast(1).Volatile();
  return qos;
}

// ---- Entities ---------------------------------------------------------------------------------

Entity::~Entity() {
  // Errors are ignored on purpose: the parent may already have deleted this child.
  if (handle_ > 0) dds_delete(handle_);
}

Entity& Entity::operator=(Entity&& other) noexcept {
  if (this != &other) {
    if (handle_ > 0) dds_delete(handle_);
    handle_ = std::exchange(other.handle_, 0);
  }
  return *this;
}

namespace {

// CheckRoudi, retried for up to kRoudiWaitMs: a service started beside RouDi (compose starts
// both at once) waits for it instead of failing.
constexpr int kRoudiWaitMs = 5000;
Status WaitForRoudi() {
  Status status = CheckRoudi();
  for (int waited_ms = 0; !status.ok() && waited_ms < kRoudiWaitMs; waited_ms += 100) {
    if (waited_ms == 0) {
      MAV_LOG(kInfo) << "waiting up to " << kRoudiWaitMs / 1000 << " s for iceoryx RouDi at "
                     << kRoudiSocket;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    status = CheckRoudi();
  }
  return status;
}

// Which RouDi: its socket file's inode and change time (a RouDi started anew makes a new file).
struct RoudiIdentity {
  bool present = false;
  ino_t inode = 0;
  int64_t ctime_ns = 0;
  bool operator==(const RoudiIdentity& o) const {
    return present == o.present && inode == o.inode && ctime_ns == o.ctime_ns;
  }
};
RoudiIdentity CurrentRoudi() {
  struct stat st {};
  if (::stat(kRoudiSocket, &st) != 0) return {};
  return {true, st.st_ino, st.st_ctim.tv_sec * 1'000'000'000LL + st.st_ctim.tv_nsec};
}

// Watches RouDi for as long as the process lives, from its first shared-memory domain on (a
// detached thread: it only stats a file, logs and signals). A RouDi that dies leaves the running
// processes streaming to each other, so that is only logged. A RouDi started anew is fatal to
// this process: its chunks are in the old RouDi's memory, and a process that joins the new one
// (a restarted service) matches it but gets none of its samples, silently. So the process asks
// itself to stop (SIGTERM: a service drains and exits, and a restart policy starts it again,
// in the new RouDi's memory).
void WatchRoudi() {
  static std::once_flag once;
  std::call_once(once, [] {
    std::thread([first = CurrentRoudi()] {
      bool gone_logged = false;
      while (true) {
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
        const RoudiIdentity now = CurrentRoudi();
        const bool answers = CheckRoudi().ok();
        if (now == first && answers) continue;
        if (!now.present || !answers || now == first) {  // gone (or its socket left behind)
          if (!gone_logged) {
            MAV_LOG(kWarning) << "iceoryx RouDi at " << kRoudiSocket
                              << " is gone: the samples in shared memory keep flowing between "
                                 "the processes already in it; a process started now cannot "
                                 "join them until every one is restarted with a new RouDi";
            gone_logged = true;
          }
          continue;
        }
        MAV_LOG(kError) << "iceoryx RouDi at " << kRoudiSocket
                        << " was restarted: this process's shared memory is the old RouDi's, and "
                           "processes in the new one would get none of its samples; stopping "
                           "(SIGTERM) so that it is started again";
        ::kill(::getpid(), SIGTERM);
        return;
      }
    }).detach();
  });
}

}  // namespace

// One dds_create_domain() per domain id and process, shared by that process's participants and
// deleted with the last one (deleting a domain deletes all its participants).
struct Participant::DomainRef {
  dds_entity_t handle = 0;
  ~DomainRef() {
    if (handle > 0) dds_delete(handle);
  }
};

Result<Participant> Participant::Create(const DdsOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  static std::mutex mutex;
  static std::map<int64_t, std::weak_ptr<DomainRef>> domains;
  std::lock_guard<std::mutex> lock(mutex);
  std::shared_ptr<DomainRef> domain = domains[options.domain].lock();
  if (domain == nullptr) {
    if (options.shared_memory) MAV_RETURN_IF_ERROR(WaitForRoudi());
    const std::string config = options.ResolvedConfig();
    const dds_entity_t handle =
        dds_create_domain(static_cast<dds_domainid_t>(options.domain), config.c_str());
    if (handle < 0) {
      return DdsStatus(handle, "dds_create_domain(" + std::to_string(options.domain) +
                                   ") with config '" + config.substr(0, 80) +
                                   "' (see the Cyclone messages above)");
    }
    if (!options.security_dir.empty()) {
      MAV_LOG(kInfo) << "DDS domain " << options.domain << ": DDS Security on, identity "
                     << options.security_dir;
    }
    if (options.shared_memory) {
      MAV_LOG(kInfo) << "DDS domain " << options.domain << ": shared memory on (iceoryx RouDi at "
                     << kRoudiSocket << ")";
      WatchRoudi();
    }
    domain = std::make_shared<DomainRef>();
    domain->handle = handle;
    domains[options.domain] = domain;
  }
  const dds_entity_t participant =
      dds_create_participant(static_cast<dds_domainid_t>(options.domain), nullptr, nullptr);
  if (participant < 0) {
    return DdsStatus(participant,
                     "dds_create_participant(domain " + std::to_string(options.domain) + ")" +
                         (options.security_dir.empty()
                              ? std::string()
                              : " with the DDS Security identity " + options.security_dir +
                                    " (refused by the security plugins: Cyclone's reason, e.g. "
                                    "an expired certificate, is printed above)"));
  }
  return Participant(std::move(domain), participant, options.domain);
}

namespace internal {

Result<dds_entity_t> CreateTopic(const Participant& participant, const std::string& name,
                                 const dds_topic_descriptor_t* descriptor) {
  const dds_entity_t topic =
      dds_create_topic(participant.handle(), descriptor, name.c_str(), nullptr, nullptr);
  if (topic < 0) return DdsStatus(topic, "dds_create_topic(" + name + ")");
  return topic;
}

Result<dds_entity_t> CreateWriter(const Participant& participant, dds_entity_t topic,
                                  const Qos& qos, const std::string& name) {
  const dds_entity_t writer = dds_create_writer(participant.handle(), topic, qos.get(), nullptr);
  if (writer < 0) return DdsStatus(writer, "dds_create_writer(" + name + ")");
  // Publication-matched is polled (MatchedReaders); enable it so the status is kept current.
  (void)dds_set_status_mask(writer, DDS_PUBLICATION_MATCHED_STATUS);
  return writer;
}

Result<dds_entity_t> CreateReader(const Participant& participant, dds_entity_t topic,
                                  const Qos& qos, const std::string& name,
                                  dds_entity_t* read_condition, dds_entity_t* waitset) {
  const dds_entity_t reader = dds_create_reader(participant.handle(), topic, qos.get(), nullptr);
  if (reader < 0) return DdsStatus(reader, "dds_create_reader(" + name + ")");
  Entity reader_guard(reader);
  (void)dds_set_status_mask(reader,
                            DDS_SUBSCRIPTION_MATCHED_STATUS | DDS_LIVELINESS_CHANGED_STATUS);
  *read_condition = dds_create_readcondition(reader, DDS_ANY_STATE);
  if (*read_condition < 0) {
    return DdsStatus(*read_condition, "dds_create_readcondition(" + name + ")");
  }
  *waitset = dds_create_waitset(participant.handle());
  if (*waitset < 0) return DdsStatus(*waitset, "dds_create_waitset(" + name + ")");
  Entity waitset_guard(*waitset);
  MAV_RETURN_IF_ERROR(DdsStatus(dds_waitset_attach(*waitset, *read_condition, reader),
                                "dds_waitset_attach(" + name + ")"));
  // Success: the caller owns both now.
  waitset_guard.Release();
  return reader_guard.Release();
}

Result<uint32_t> MatchedReaders(dds_entity_t writer, const std::string& name) {
  dds_publication_matched_status_t status;
  MAV_RETURN_IF_ERROR(DdsStatus(dds_get_publication_matched_status(writer, &status),
                                "dds_get_publication_matched_status(" + name + ")"));
  return status.current_count;
}

Result<uint32_t> MatchedWriters(dds_entity_t reader, const std::string& name) {
  dds_subscription_matched_status_t status;
  MAV_RETURN_IF_ERROR(DdsStatus(dds_get_subscription_matched_status(reader, &status),
                                "dds_get_subscription_matched_status(" + name + ")"));
  return status.current_count;
}

Result<uint32_t> AliveWriters(dds_entity_t reader, const std::string& name) {
  dds_liveliness_changed_status_t status;
  MAV_RETURN_IF_ERROR(DdsStatus(dds_get_liveliness_changed_status(reader, &status),
                                "dds_get_liveliness_changed_status(" + name + ")"));
  return status.alive_count;
}

Status WaitForMatch(dds_entity_t entity, bool is_writer, uint32_t count, int64_t timeout_ns,
                    const std::string& name) {
  // Matching happens on Cyclone's discovery threads; polling every 5 ms is simple and cheap.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  while (true) {
    MAV_ASSIGN_OR_RETURN(uint32_t matched,
                         is_writer ? MatchedReaders(entity, name) : MatchedWriters(entity, name));
    if (matched >= count) return Status::Ok();
    if (std::chrono::steady_clock::now() >= deadline) {
      return Status::Unavailable(std::string(is_writer ? "writer" : "reader") + " on " + name +
                                 ": " + std::to_string(matched) + " of " + std::to_string(count) +
                                 " " + (is_writer ? "readers" : "writers") + " matched within " +
                                 std::to_string(timeout_ns / 1'000'000) + " ms");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

Result<bool> WaitForData(dds_entity_t waitset, int64_t timeout_ns, const std::string& name) {
  const dds_return_t n = dds_waitset_wait(waitset, nullptr, 0, timeout_ns);
  if (n < 0) return DdsStatus(n, "dds_waitset_wait(" + name + ")");
  return n > 0;
}

namespace {
void CallOnData(dds_entity_t /*reader*/, void* on_data) {
  (*static_cast<std::function<void()>*>(on_data))();
}
}  // namespace

Status SetDataListener(dds_entity_t reader, std::function<void()>* on_data,
                       const std::string& name) {
  dds_listener_t* listener = dds_create_listener(on_data);
  if (listener == nullptr) return Status::Internal("dds_create_listener(" + name + ") failed");
  dds_lset_data_available(listener, on_data != nullptr ? &CallOnData : nullptr);
  // dds_set_listener copies the listener; with a null one it waits for callbacks in progress.
  const dds_return_t ret = dds_set_listener(reader, on_data != nullptr ? listener : nullptr);
  dds_delete_listener(listener);
  return DdsStatus(ret, "dds_set_listener(" + name + ")");
}

}  // namespace internal

}  // namespace mav::transport
