#include "backends/mpi/mpi_cluster.h"

#include <cstdlib>
#include <string>

#include "backends/mpi/mpi_channel.h"
#include "core/util/errors.h"

namespace tandem::mpi {

Fault parse_fault(const char* text) {
  Fault f;
  if (!text || !*text) return f;
  const std::string s = text;
  const size_t at = s.find('@');
  const std::string kind = s.substr(0, at);
  const std::string usage =
      "TANDEM_MPI_FAULT must be KIND@RANK with KIND one of throw, oom, "
      "hang, exit, version and RANK a worker rank >= 1, got '" +
      s + "'";
  if (at == std::string::npos) throw InputError(usage);
  char* end = nullptr;
  const long r = std::strtol(s.c_str() + at + 1, &end, 10);
  if (at + 1 == s.size() || *end != '\0' || r < 1 || r > 1 << 20) throw InputError(usage);
  f.rank = int(r);
  if (kind == "throw")
    f.kind = FaultKind::kThrow;
  else if (kind == "oom")
    f.kind = FaultKind::kOom;
  else if (kind == "hang")
    f.kind = FaultKind::kHang;
  else if (kind == "exit")
    f.kind = FaultKind::kExit;
  else if (kind == "version")
    f.kind = FaultKind::kVersion;
  else
    throw InputError(usage);
  return f;
}

int start() {
  initialize();
  return rank();
}

int rank_count() {
  return size();
}

namespace {
std::vector<WorkerInfo>& workers() {
  static std::vector<WorkerInfo> w;
  return w;
}
bool g_connected = false;
}  // namespace

std::vector<std::unique_ptr<MpiPeerBackend>> connect_peers() {
  PeerSettings settings;
  settings.timeout_s = answer_timeout_seconds();
  parse_fault(std::getenv("TANDEM_MPI_FAULT"));  // a bad value ends the run here too
  if (!g_connected) {
    const std::string mine = build_fingerprint();
    for (int r = 1; r < size(); ++r) {
      const Message m = receive(r, settings.timeout_s, "its handshake");
      WireReader in(m.bytes, "handshake of rank " + std::to_string(r));
      if (m.tag == kTagError) throw RankFailure(r, in.get_string());
      if (m.tag != kTagHello) throw RankFailure(r, "did not start with a handshake");
      const uint32_t protocol = in.get<uint32_t>();
      if (protocol != kProtocolVersion) {
        throw RankFailure(r, "speaks protocol version " + std::to_string(protocol) +
                                 ", rank 0 speaks " + std::to_string(kProtocolVersion) +
                                 ": every rank must run the same tandem build");
      }
      const std::string theirs = in.get_string();
      if (theirs != mine) {
        throw RankFailure(r, "was built with other kernel data layouts (" + theirs + "; rank 0: " +
                                 mine + "): every rank must run the same tandem build");
      }
      WorkerInfo info;
      info.rank = r;
      info.backends = in.get_string();
      info.needs_bvh = in.get<uint8_t>() != 0;
      workers().push_back(info);
    }
    g_connected = true;
  }
  std::vector<std::unique_ptr<MpiPeerBackend>> peers;
  for (const WorkerInfo& w : workers())
    peers.push_back(std::make_unique<MpiPeerBackend>(w, settings));
  return peers;
}

void finish() {
  if (!initialized()) return;
  if (rank() == 0) {
    const double timeout = answer_timeout_seconds();
    // Workers that never connected (an error before the first frame) are
    // left to the exit-time abort.
    for (const WorkerInfo& w : workers())
      send(w.rank, kTagShutdown, {}, timeout);
    if (!g_connected && size() > 1) return;
  }
  finalize();
}

}  // namespace tandem::mpi
