// The worker's test-only renderer fault (worker/render_fault.h): what --test-render-fault
// accepts, that each kind fails as it says, only for the named scene when one is given, and
// that the default fails nothing.

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "core/util/arguments.h"
#include "worker/render_fault.h"

namespace render::service {
namespace {

TEST(RenderFault, ParsesTheThreeKindsAndRefusesTheRest) {
    const RenderFault t = RenderFault::parse("throw:cannot render: here");
    EXPECT_EQ(t.kind, RenderFault::Kind::kThrow);
    EXPECT_EQ(t.message, "cannot render: here");
    EXPECT_EQ(RenderFault::parse("non-std").kind, RenderFault::Kind::kThrowNonStd);
    EXPECT_EQ(RenderFault::parse("abort").kind, RenderFault::Kind::kAbort);
    for (const char* bad : {"", "throw:", "throw", "Abort", "crash", "non-std:x"})
        EXPECT_THROW(RenderFault::parse(bad), UsageError) << bad;
}

TEST(RenderFault, EachKindFailsAsItSays) {
    EXPECT_NO_THROW(RenderFault{}.raise("scene.xml"));
    try {
        RenderFault::parse("throw:the message").raise("scene.xml");
        ADD_FAILURE() << "did not throw";
    } catch (const std::runtime_error& e) {
        EXPECT_STREQ(e.what(), "the message");
    }
    bool non_std = false;
    try {
        RenderFault::parse("non-std").raise("scene.xml");
    } catch (const std::exception&) {
        ADD_FAILURE() << "a std::exception";
    } catch (...) {
        non_std = true;
    }
    EXPECT_TRUE(non_std);
    EXPECT_DEATH(RenderFault::parse("abort").raise("scene.xml"), "");
}

TEST(RenderFault, OnlyTheNamedSceneFailsWhenOneIsNamed) {
    RenderFault fault = RenderFault::parse("throw:poisoned");
    fault.scene_name = "poison.xml";
    EXPECT_THROW(fault.raise("poison.xml"), std::runtime_error);
    EXPECT_THROW(fault.raise("jobs/a/poison.xml"), std::runtime_error);
    EXPECT_NO_THROW(fault.raise("scene.xml"));
    EXPECT_NO_THROW(fault.raise("poison.xml/scene.xml"));
    fault.kind = RenderFault::Kind::kAbort;
    fault.raise("healthy.xml");  // returns: only poison.xml aborts
}

}  // namespace
}  // namespace render::service
