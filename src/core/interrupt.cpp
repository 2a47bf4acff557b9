#include "core/interrupt.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

namespace egopd {
namespace {

std::atomic<int> g_signal{0};

const char* signal_name(int sig) {
  switch (sig) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    default: return "signal";
  }
}

extern "C" void on_signal(int sig) {
  int expected = 0;
  if (!g_signal.compare_exchange_strong(expected, sig)) _exit(128 + sig);  // second signal: stop now
}

}  // namespace

Interrupted::Interrupted(int sig, const std::string& where)
    : Error(std::string("interrupted by ") + signal_name(sig) + (where.empty() ? "" : " " + where) +
            ": stopped, no partial output left"),
      signal_(sig) {}

void install_interrupt_handlers() {
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: a blocking read returns EINTR and the caller reaches a safe point sooner
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  // A file-size limit (ulimit -f) then fails the write with EFBIG, reported like a full disk, instead of killing
  // the process with temporary files left behind.
  ::signal(SIGXFSZ, SIG_IGN);
}

int pending_interrupt() { return g_signal.load(std::memory_order_relaxed); }

void throw_if_interrupted(const std::string& where) {
  const int sig = pending_interrupt();
  if (sig == 0) return;
  throw Interrupted(sig, where);
}

void clear_interrupt() { g_signal.store(0); }

void request_interrupt(int sig) { g_signal.store(sig); }

}  // namespace egopd
