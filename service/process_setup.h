#pragma once

// Process-wide settings every gRPC program of the service (server, worker, client) makes first
// thing in main().

namespace render::service {

// Turns off abseil's mutex deadlock detection. Debian builds abseil with it on (a debug
// default): every absl::Mutex lock, and gRPC takes them on every call, then records the locks
// held in a cycle graph. A nested lock pair costs ~170 ns with it and ~40 ns without
// (docs/results/performance.md, "Distribution overhead"). It finds lock-order bugs in abseil's
// users, not in ours, and release builds of abseil have it off.
void prepare_grpc_process();

}  // namespace render::service
