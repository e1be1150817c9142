#include "service/server_list.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace render::service {
namespace {

TEST(ServerList, OneAddressIsAListOfOne) {
    EXPECT_EQ(split_server_list("127.0.0.1:50051"), std::vector<std::string>{"127.0.0.1:50051"});
}

TEST(ServerList, KeepsTheOrderAndTrimsBlanks) {
    EXPECT_EQ(split_server_list("a.example:1, b.example:2 ,[::1]:3"),
              (std::vector<std::string>{"a.example:1", "b.example:2", "[::1]:3"}));
}

TEST(ServerList, RefusesEmptyEntriesMissingPortsAndRepeats) {
    for (const char* bad : {"", ",", "a:1,", "a:1,,b:2", "a", "a:", ":1", "a:1x", "a:1,a:1"})
        EXPECT_THROW(split_server_list(bad), std::invalid_argument) << bad;
}

}  // namespace
}  // namespace render::service
