#pragma once

// A fault injected into a worker's renderer, for the tests of what a worker does when rendering
// fails (docs/guide/reliability.md, "A lease the renderer cannot render"): the real causes are
// refused at load, so tests need a renderer that fails on demand. Only the worker's
// `--test-render-fault` flag sets one (never the environment, never a job), so a production
// worker cannot meet it by accident; without the flag the lease path pays one comparison.

#include <string>

namespace render::service {

struct RenderFault {
    enum class Kind {
        kNone,
        kThrow,        // a std::runtime_error carrying `message`
        kThrowNonStd,  // an exception that is not a std::exception
        kAbort,        // std::abort(), as Embree's assertion on an invalid ray did: the worker dies
    };
    Kind kind = Kind::kNone;
    std::string message;
    // Only leases of jobs whose scene file has this name (e.g. "poison.xml") fail; empty:
    // every lease. Lets a test farm render healthy jobs beside the failing one.
    std::string scene_name;

    // "throw:MESSAGE", "non-std" or "abort"; throws UsageError for anything else.
    static RenderFault parse(const std::string& text);
    // Throws or aborts as `kind` says for a lease of the scene at `scene_path` (the bundle's
    // path); returns at once for kNone or another scene.
    void raise(const std::string& scene_path) const;
};

}  // namespace render::service
