// `scan2model devices` against the emulated board (tests/emulated_horus_board.h): the command runs as a child
// process under the same umockdev testbed (it inherits LD_PRELOAD and UMOCKDEV_DIR; its ioctls reach this
// process's handler through the testbed's socket).

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "emulated_horus_board.h"
#include "test_support.h"

namespace s2m {
namespace {

using test::EmulatedHorusBoard;

class DevicesCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!EmulatedHorusBoard::InMockEnvironment()) {
      GTEST_SKIP() << "not running under umockdev-wrapper: the emulated USB board is unavailable";
    }
  }
};

TEST_F(DevicesCommandTest, ListsTheEmulatedBoard) {
  EmulatedHorusBoard emu;
  const test::ShellResult text = test::Shell(std::string(S2M_CLI_PATH) + " devices", false);
  ASSERT_EQ(text.exit_code, 0) << text.out;
  EXPECT_NE(
      text.out.find("usb     2341:0043  bus 1 address 5  Arduino board (CDC-ACM)  'Arduino (www.arduino.cc) "
                    "Horus turntable (emulated)'  serial EMU0001"),
      std::string::npos)
      << text.out;
  EXPECT_EQ(text.out.find("no supported device found"), std::string::npos) << text.out;

  const test::ShellResult json = test::Shell(std::string(S2M_CLI_PATH) + " devices --json", false);
  ASSERT_EQ(json.exit_code, 0) << json.out;
  const nlohmann::json j = nlohmann::json::parse(json.out);
  EXPECT_EQ(j["schema"], "scan2model.devices/1");
  ASSERT_EQ(j["usb"].size(), 1u);
  const nlohmann::json& d = j["usb"][0];
  EXPECT_EQ(d["vendor_id"], "2341");
  EXPECT_EQ(d["product_id"], "0043");
  EXPECT_EQ(d["bus"], 1);
  EXPECT_EQ(d["address"], 5);
  EXPECT_EQ(d["serial_number"], "EMU0001");
  EXPECT_EQ(d["product"], "Horus turntable (emulated)");
  EXPECT_EQ(d["cdc_acm"], true);
  EXPECT_EQ(d["driver"], "horus");
  EXPECT_TRUE(j["cameras"].is_array());
  EXPECT_FALSE(j.contains("usb_error"));
}

TEST_F(DevicesCommandTest, NothingConnectedGivesHints) {
  EmulatedHorusBoard::Options o;
  o.vendor_id = 0x046d;  // a Logitech device: not one of ours
  o.product_id = 0xc52b;
  EmulatedHorusBoard emu(o);
  const test::ShellResult json = test::Shell(std::string(S2M_CLI_PATH) + " devices --json", false);
  ASSERT_EQ(json.exit_code, 0) << json.out;
  const nlohmann::json j = nlohmann::json::parse(json.out);
  EXPECT_EQ(j["usb"].size(), 0u);
  ASSERT_GE(j["hints"].size(), 3u);
  EXPECT_NE(j["hints"][2].get<std::string>().find("docs/devices.md"), std::string::npos);
  const test::ShellResult text = test::Shell(std::string(S2M_CLI_PATH) + " devices", false);
  EXPECT_EQ(text.exit_code, 0);
  EXPECT_NE(text.out.find("no supported"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("hint: connect the scanner's board by USB"), std::string::npos) << text.out;
}

}  // namespace
}  // namespace s2m
