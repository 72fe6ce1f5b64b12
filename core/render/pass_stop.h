// A long pass on the CPU (the feature pass, the SVGF filter) asks its
// PassStop between its parts, on the thread that called the pass: true
// stops the pass there, its output left incomplete. An empty PassStop never
// stops. The viewer reads input in it, so that no key waits for a
// full-resolution pass to end (app/view/view_session.h).
#pragma once

#include <functional>

namespace tandem {

using PassStop = std::function<bool()>;

// Whether `stop` asks the pass to stop now.
inline bool pass_should_stop(const PassStop& stop) {
  return stop && stop();
}

}  // namespace tandem
