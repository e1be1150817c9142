// The request's render options (service/request_options.h): the typed fields of older clients
// fold into the options map, disagreement is refused, names and values are checked against the
// render options table, and a stored request carries exactly its options.

#include <gtest/gtest.h>

#include "service/request_options.h"

namespace render::service {
namespace {

TEST(RequestOptions, TypedFieldsFoldIntoTheMap) {
    v1::RenderSettings s;
    s.set_seed(7);
    s.set_radius_factor(0.01);
    s.set_alpha(0.5);
    s.set_max_depth(0);
    s.set_has_max_depth(true);
    s.set_light_path_count(100);
    (*s.mutable_options())["mis"] = "balance";
    EXPECT_EQ(request_options(s), (OptionMap{{"alpha", "0.5"},
                                             {"light_paths", "100"},
                                             {"max_depth", "0"},
                                             {"mis", "balance"},
                                             {"radius_factor", "0.01"},
                                             {"seed", "7"}}));
    // Zero means unset for the typed fields (max_depth: has_max_depth).
    EXPECT_TRUE(request_options(v1::RenderSettings()).empty());
}

TEST(RequestOptions, TheSameValueSpelledTwiceIsFineDifferentValuesAreRefused) {
    v1::RenderSettings s;
    s.set_alpha(0.5);
    (*s.mutable_options())["alpha"] = "5e-1";
    EXPECT_EQ(request_options(s).at("alpha"), "5e-1");
    (*s.mutable_options())["alpha"] = "0.6";
    EXPECT_THROW(request_options(s), std::invalid_argument);
}

TEST(RequestOptions, NamesAndValuesAreChecked) {
    EXPECT_EQ(check_request_options({{"alpha", "0.5"}, {"mis", "power"}}), "");
    EXPECT_NE(check_request_options({{"radius", "1"}}).find("\"radius\""), std::string::npos);
    EXPECT_NE(check_request_options({{"alpha", "2"}}).find("alpha"), std::string::npos);
    EXPECT_NE(check_request_options({{"seed", "-1"}}).find("seed"), std::string::npos);
}

TEST(RequestOptions, StoredOptionsReplaceTheTypedFields) {
    v1::RenderSettings s;
    s.set_alpha(0.5);
    s.set_has_max_depth(true);
    s.set_max_depth(3);
    const std::string stale_name = "stale", stale_value = "x";
    (*s.mutable_options())[stale_name] = stale_value;
    set_request_options(s, {{"alpha", "0.5"}, {"max_depth", "3"}, {"seed", "11"}});
    EXPECT_EQ(s.alpha(), 0.0);
    EXPECT_FALSE(s.has_max_depth());
    EXPECT_EQ(s.seed(), 11u);
    EXPECT_EQ(s.options().count("stale"), 0u);
    EXPECT_EQ(request_options(s),
              (OptionMap{{"alpha", "0.5"}, {"max_depth", "3"}, {"seed", "11"}}));
}

}  // namespace
}  // namespace render::service
