// The client's animation frames (client/frames.h): --frames ranges, {frame} substitution,
// frames files with file:line errors, fetch's frame file names, and watch's frame strip
// (client/progress.h).

#include "client/frames.h"

#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "client/progress.h"
#include "core/util/arguments.h"

namespace {

using namespace render::service;
using render::UsageError;

std::string usage_message(const std::function<void()>& f) {
    try {
        f();
    } catch (const UsageError& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(ClientFrames, RangeIncludesBothEnds) {
    FrameRange r = parse_frame_range("0:24");
    EXPECT_EQ(r.first, 0);
    EXPECT_EQ(r.last, 24);
    EXPECT_EQ(r.count(), 25);
    EXPECT_EQ(parse_frame_range("7:7").count(), 1);
    EXPECT_EQ(parse_frame_range("10:1009").count(), 1000);
}

TEST(ClientFrames, BadRangesSayWhy) {
    EXPECT_NE(usage_message([] { parse_frame_range("24"); }).find("expected FIRST:LAST"),
              std::string::npos);
    EXPECT_NE(usage_message([] { parse_frame_range("5:2"); }).find("comes before the first 5"),
              std::string::npos);
    EXPECT_NE(usage_message([] { parse_frame_range("-1:3"); }).find("\"-1\" is not a frame"),
              std::string::npos);
    EXPECT_NE(usage_message([] { parse_frame_range("0:x"); }).find("\"x\" is not a frame"),
              std::string::npos);
    EXPECT_NE(usage_message([] { parse_frame_range(":3"); }).find("is not a frame"),
              std::string::npos);
    EXPECT_NE(usage_message([] {
                  parse_frame_range("0:1000");
              }).find("1001 frames exceed the limit of 1000"),
              std::string::npos);
}

TEST(ClientFrames, SubstitutesTheFrameNumber) {
    EXPECT_EQ(substitute_frame("{frame}", 7), "7");
    EXPECT_EQ(substitute_frame("mesh_{frame:04}.obj", 7), "mesh_0007.obj");
    EXPECT_EQ(substitute_frame("{frame:4}", 12345), "12345");  // wider than the padding
    EXPECT_EQ(substitute_frame("{frame}+{frame:02}", 3), "3+03");
    EXPECT_EQ(substitute_frame("0, {x}, 1", 3), "0, {x}, 1");  // other braces stay
    EXPECT_EQ(substitute_frame("no placeholder", 3), "no placeholder");
    EXPECT_TRUE(has_frame_placeholder("a{frame:03}"));
    EXPECT_FALSE(has_frame_placeholder("a{fram}"));
    EXPECT_NE(usage_message([] { substitute_frame("{frame:x}", 1); }).find("\"{frame:x}\""),
              std::string::npos);
    EXPECT_NE(usage_message([] { substitute_frame("{frames}", 1); }).find("\"{frames}\""),
              std::string::npos);
    EXPECT_NE(usage_message([] { substitute_frame("{frame:0}", 1); }).find("1 <= N <= 9"),
              std::string::npos);
    EXPECT_NE(usage_message([] { substitute_frame("{frame", 1); }).find("unterminated"),
              std::string::npos);
}

TEST(ClientFrames, RangeFramesCarryOnlyTheTemplatedDefines) {
    std::vector<Defines> frames = range_frames(
        parse_frame_range("2:4"), {{"x", "{frame}"}, {"spp", "8"}, {"f", "a{frame:03}"}});
    ASSERT_EQ(frames.size(), 3u);
    EXPECT_EQ(frames[0], (Defines{{"x", "2"}, {"f", "a002"}}));
    EXPECT_EQ(frames[2], (Defines{{"x", "4"}, {"f", "a004"}}));
}

TEST(ClientFrames, FramesFileParsesAndSkips) {
    std::vector<Defines> frames = parse_frames_text(
        "# power per frame\npower=1 x=0.5\n\n   # indented comment\r\npower=2\tx=\n-\n", "f.txt");
    ASSERT_EQ(frames.size(), 3u);
    EXPECT_EQ(frames[0], (Defines{{"power", "1"}, {"x", "0.5"}}));
    EXPECT_EQ(frames[1], (Defines{{"power", "2"}, {"x", ""}}));
    EXPECT_TRUE(frames[2].empty());
}

TEST(ClientFrames, FramesFileErrorsNameFileAndLine) {
    EXPECT_EQ(usage_message([] {
                  parse_frames_text("a=1\n\nb=2 oops\n", "anim.txt");
              }).rfind("anim.txt:3: \"oops\" is not name=value", 0),
              0u);
    EXPECT_EQ(usage_message([] {
                  parse_frames_text("a=1 a=2\n", "anim.txt");
              }).rfind("anim.txt:1: \"a\" is given twice", 0),
              0u);
    EXPECT_EQ(usage_message([] {
                  parse_frames_text("=1\n", "anim.txt");
              }).rfind("anim.txt:1: \"=1\" is not name=value", 0),
              0u);
    EXPECT_EQ(usage_message([] {
                  parse_frames_text("- a=1\n", "anim.txt");
              }).rfind("anim.txt:1: \"-\"", 0),
              0u);
    EXPECT_EQ(usage_message([] { parse_frames_text("# nothing\n\n", "anim.txt"); }),
              "anim.txt: no frames (every line is blank or a comment)");
    std::string many;
    for (int i = 0; i < 1001; ++i) many += "a=" + std::to_string(i) + "\n";
    EXPECT_EQ(usage_message([&] {
                  parse_frames_text(many, "anim.txt");
              }).rfind("anim.txt:1001: more than 1000 frames", 0),
              0u);
    EXPECT_EQ(usage_message([] {
                  read_frames_file("/nonexistent/frames.txt");
              }).rfind("--frames-file /nonexistent/frames.txt: cannot read", 0),
              0u);
}

TEST(ClientFrames, FileNamesAndDefinesText) {
    EXPECT_EQ(frame_file_name(0), "frame_0000.exr");
    EXPECT_EQ(frame_file_name(999), "frame_0999.exr");
    EXPECT_EQ(format_defines({{"b", "2"}, {"a", "1"}}), "a=1 b=2");
    EXPECT_EQ(format_defines({}), "(no overrides)");
}

TEST(ClientFrames, WatchStripShowsEveryFrame) {
    render::v1::Job job;
    job.mutable_settings()->set_iterations(10);
    auto add = [&](uint64_t done_iterations, bool done) {
        render::v1::FrameStatus* f = job.add_frames();
        f->set_index(uint32_t(job.frames_size() - 1));
        f->set_iterations_target(10);
        f->set_iterations_done(done_iterations);
        f->set_done(done);
    };
    add(10, true);
    add(7, false);
    add(0, false);
    add(3, false);
    EXPECT_EQ(frame_strip(job), "frames 1/4 done [#7.3]");
    // Two frames per mark: the least advanced of each pair.
    EXPECT_EQ(frame_strip(job, 2), "frames 1/4 done [7.] (2 frames per mark)");
}

}  // namespace
