#include "service/process_setup.h"

#include <absl/synchronization/mutex.h>

namespace render::service {

void prepare_grpc_process() {
    absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
}

}  // namespace render::service
