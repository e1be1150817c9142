// The camera's and the lights' transforms are checked at load as shapes' and instances' are
// (ray_transform_problem, core/base/ray_transform_check.h): camera rays and light paths start
// from them, so a singular, near-singular or over-shrinking one is refused at its line, in both
// the Mitsuba and the pbrt loader; ordinary ones (mirrors, look-ats, uniform scales) load.

#include <gtest/gtest.h>

#include <string>

#include "core/base/error.h"
#include "core/scene/loader/scene_loader.h"
#include "core/scene/pbrt/scene_loader.h"

namespace render {
namespace {

const std::string kTests = std::string(RENDER_SOURCE_DIR) + "/scenes/tests/";

// "loaded", or the loader's message.
std::string mitsuba_message(const std::string& body) {
    try {
        load_scene_from_string(
            "<scene version=\"3.0.0\">\n" + body + "<shape type=\"sphere\"/>\n</scene>\n", kTests);
    } catch (const SceneError& e) {
        return e.what();
    }
    return "loaded";
}

std::string pbrt_message(const std::string& text) {
    try {
        pbrt::load_scene_from_string(text, kTests);
    } catch (const SceneError& e) {
        return e.what();
    }
    return "loaded";
}

void expect_refused(const std::string& message, const std::string& where, const std::string& what) {
    EXPECT_NE(message.find(where), std::string::npos) << message;
    EXPECT_NE(message.find(what), std::string::npos) << message;
}

// A sensor whose to_world holds `transform` (line 3 of the scene).
std::string sensor(const std::string& transform) {
    return "<sensor type=\"perspective\"><float name=\"fov\" value=\"40\"/>\n"
           "  <transform name=\"to_world\">" +
           transform + "</transform>\n</sensor>\n";
}

TEST(CameraLightTransform, MitsubaRefusesACameraRaysCannotStartFromAtItsLine) {
    expect_refused(mitsuba_message(sensor("<scale x=\"1\" y=\"1\" z=\"1e-30\"/>")), "<string>:3",
                   "the transform is near-singular");
    expect_refused(mitsuba_message(sensor("<scale x=\"1\" y=\"0\" z=\"1\"/>")), "<string>:3",
                   "the transform is singular");
    expect_refused(mitsuba_message(sensor("<scale value=\"1e-7\"/>")), "<string>:3",
                   "shrinks too much");
    EXPECT_EQ(mitsuba_message(sensor("<scale x=\"-1\"/><lookat origin=\"0 0 -5\" target=\"0 0 0\" "
                                     "up=\"0 1 0\"/>")),
              "loaded");
}

// An emitter whose to_world holds `transform` (line 5), after a plain sensor.
std::string emitter(const std::string& type, const std::string& transform) {
    return "<sensor type=\"perspective\"/>\n<emitter type=\"" + type + "\">\n  <rgb name=\"" +
           (type == "directional" ? "irradiance" : "intensity") +
           "\" value=\"1\"/>\n  <transform name=\"to_world\">" + transform +
           "</transform>\n</emitter>\n";
}

TEST(CameraLightTransform, MitsubaRefusesALightRaysCannotStartFromAtItsLine) {
    for (const char* type : {"point", "spot", "directional"}) {
        SCOPED_TRACE(type);
        expect_refused(mitsuba_message(emitter(type, "<scale x=\"1\" y=\"1\" z=\"1e-30\"/>")),
                       "<string>:5", "the transform is near-singular");
        expect_refused(mitsuba_message(emitter(type, "<scale value=\"0\"/>")), "<string>:5",
                       "the transform is singular");
        EXPECT_EQ(mitsuba_message(emitter(type, "<lookat origin=\"1 2 3\" target=\"0 0 0\"/>")),
                  "loaded");
    }
    // Before the check a flattened directional light loaded (its direction (0, 0, 1e-30) is
    // finite and non-zero).
    expect_refused(mitsuba_message(emitter("directional", "<scale z=\"1e-30\"/>")), "<string>:5",
                   "near-singular");
}

const std::string kFilm = "Film \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 8\n";

TEST(CameraLightTransform, PbrtRefusesACameraRaysCannotStartFromAtItsLine) {
    expect_refused(pbrt_message("Scale 1 1 1e-30\nLookAt 0 0 -5  0 0 0  0 1 0\n"
                                "Camera \"perspective\"\n" +
                                kFilm + "WorldBegin\n"),
                   "<string>:3", "Camera: the transform is near-singular");
    expect_refused(pbrt_message("Scale 0 1 1\nCamera \"perspective\"\n" + kFilm + "WorldBegin\n"),
                   "<string>:2", "Camera: the transform is singular");
    // The camera's to_world is the inverse of the current transform: a huge scale here is a
    // tiny one there.
    expect_refused(
        pbrt_message("Scale 1e7 1e7 1e7\nCamera \"perspective\"\n" + kFilm + "WorldBegin\n"),
        "<string>:2", "Camera: the transform shrinks too much");
    EXPECT_EQ(pbrt_message("Scale -1 1 1\nLookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\n" +
                           kFilm + "WorldBegin\n"),
              "loaded");
}

TEST(CameraLightTransform, PbrtRefusesALightRaysCannotStartFromAtItsLine) {
    const std::string header = "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\n" + kFilm +
                               "WorldBegin\nShape \"sphere\"\n";  // lines 1-5
    for (const char* light :
         {"LightSource \"point\" \"point3 from\" [0 2 0]\n",
          "LightSource \"spot\" \"point3 from\" [0 2 0] \"point3 to\" [0 0 0]\n",
          "LightSource \"distant\" \"point3 from\" [0 2 0] \"point3 to\" [0 0 0]\n"}) {
        SCOPED_TRACE(light);
        expect_refused(
            pbrt_message(header + "AttributeBegin\nScale 1 1 1e-30\n" + light + "AttributeEnd\n"),
            "<string>:8", "LightSource: the transform is near-singular");
        expect_refused(pbrt_message(header + "Scale 1 0 1\n" + light), "<string>:7",
                       "LightSource: the transform is singular");
        EXPECT_EQ(pbrt_message(header + "Rotate 30 0 1 0\nScale 2 2 2\n" + light), "loaded");
    }
}

}  // namespace
}  // namespace render
