#pragma once
// SIGINT / SIGTERM as a clean stop: the handler only records the signal; long work polls at safe points (between
// sampler steps, decode chunks, clips) and throws Interrupted, so destructors remove temporary files and folders on
// the way out. The command then exits 128 + signal (130 for SIGINT, 143 for SIGTERM) with one line.
#include <string>

#include "core/error.h"

namespace egopd {

class Interrupted : public Error {
 public:
  Interrupted(int signal, const std::string& where);
  int signal() const { return signal_; }
  int exit_code() const { return 128 + signal_; }

 private:
  int signal_;
};

// Installs the handlers (idempotent) and ignores SIGXFSZ (an exceeded file-size limit becomes a write error). A second signal while the first is being handled ends the process at once
// (the user insists), with the same exit code.
void install_interrupt_handlers();
// The signal received so far, or 0.
int pending_interrupt();
// Throws Interrupted when a signal arrived. `where` names the safe point in the message ("after step 3 of 25").
void throw_if_interrupted(const std::string& where = "");
// Forgets a received signal (tests; a library caller that handled the stop itself).
void clear_interrupt();
// Records `signal` as if it had been delivered (tests, and a library caller's own cancellation).
void request_interrupt(int signal);

}  // namespace egopd
