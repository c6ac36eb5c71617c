// `fleetgw ride plot` against the real binary on a store written through the real Store
// (ride_plot_store.h): `latest` and a ride id, only the ride's window of telemetry, the hostile
// ride id escaped, gaps kept, `--out -`, the store left untouched, the GNSS track as a map panel
// (a note without one, a warning and no panel for a damaged one), and the exit codes (unknown
// ride 1, not a store 2, usage errors 2, unwritable output 1).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "storage/sqlite.h"
#include "tests/config/cli_test_util.h"
#include "tests/config/ride_plot_store.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing::ride_plot_cli {
namespace {

namespace fs = std::filesystem;
namespace rs = ride_plot_store;

std::size_t occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

std::string series_d(const std::string& svg, const std::string& name) {
  const auto at = svg.find("class=\"series series-" + name + "\"");
  if (at == std::string::npos) return "";
  const auto d = svg.find(" d=\"", at);
  return svg.substr(d + 4, svg.find('"', d + 4) - d - 4);
}

class RidePlotCli : public ::testing::Test {
 protected:
  void SetUp() override { rs::write_ride_store(db_); }
  Result plot(std::vector<std::string> args) {
    args.insert(args.begin(), {FLEETGW_BIN, "ride", "plot"});
    return run(args, dir_.path());
  }

  TempDir dir_{"fleetgw-ride-plot"};
  fs::path db_ = dir_.path() / "fleetgw.db";
  fs::path svg_ = dir_.path() / "ride.svg";
};

TEST_F(RidePlotCli, LatestRideWithItsWindowGapsAndEscapedId) {
  const std::string before = read_text_file(db_);
  const Result r = plot({"latest", "--db", db_.string(), "--out", svg_.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find(svg_.string() + ": ride "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(std::to_string(rs::kLatestSamples) + " samples over 28.0 min"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(occurrences(r.out, "\n"), 1u) << "the hostile id broke the line: " << r.out;

  const std::string svg = read_text_file(svg_);
  EXPECT_TRUE(svg.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg "));
  EXPECT_TRUE(svg.ends_with("</svg>\n"));
  EXPECT_EQ(svg.find("<script"), std::string::npos);
  EXPECT_NE(svg.find(">Ride &lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &apos;q&apos; "
                     "\\x1b[2J\\nnext\xef\xbf\xbd</text>"),
            std::string::npos)
      << svg.substr(0, 800);
  EXPECT_NE(svg.find("2024-11-27T10:00:00Z \u00b7 8.10 km \u00b7 28.0 min \u00b7 " +
                     std::to_string(rs::kLatestSamples) + " samples"),
            std::string::npos);
  // Only the ride's own samples: the 999 km/h outside the window would set a 1000 km/h scale.
  EXPECT_EQ(svg.find(">1000</text>"), std::string::npos);
  EXPECT_NE(svg.find("text-anchor=\"end\">30</text>"), std::string::npos);  // speed scale top
  // Gaps: the gateway down from 10 to 12 min, speed missing from 20 to 21 min.
  EXPECT_EQ(occurrences(series_d(svg, "speed"), "M"), 3u);
  EXPECT_EQ(occurrences(series_d(svg, "power"), "M"), 2u);
  EXPECT_EQ(occurrences(series_d(svg, "soc"), "M"), 2u);
  EXPECT_EQ(occurrences(series_d(svg, "assist"), "M"), 2u);
  // Assist steps with the built-in U7 names: eco, norm, sport.
  for (const char* name : {">eco</text>", ">norm</text>", ">sport</text>"}) {
    EXPECT_NE(svg.find(name), std::string::npos) << name;
  }
  EXPECT_EQ(occurrences(svg, "class=\"axis axis-y\""), 4u);
  // The ride's GNSS track: a map panel with its five positions and the caption.
  EXPECT_NE(svg.find("id=\"panel-map\""), std::string::npos);
  EXPECT_EQ(occurrences(svg, "<polyline class=\"track\""), 1u);
  const auto points = svg.find(" points=\"", svg.find("<polyline class=\"track\""));
  EXPECT_EQ(occurrences(svg.substr(points, svg.find('"', points + 9) - points), ","),
            rs::kLatestTrack.size());
  EXPECT_NE(svg.find(">GNSS 6.7 km, odometer 8.1 km</text>"), std::string::npos);
  EXPECT_EQ(svg.find("no GNSS track"), std::string::npos);
  // Inspection never modifies the store.
  EXPECT_EQ(read_text_file(db_), before);
}

TEST_F(RidePlotCli, RideByIdToStdout) {
  const Result r = plot({"ride-normal", "--db", db_.string(), "--out", "-"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.out.starts_with("<?xml")) << r.out.substr(0, 200);
  EXPECT_NE(r.out.find("<title>Ride ride-normal</title>"), std::string::npos);
  EXPECT_NE(r.out.find("2024-11-27T09:00:00Z \u00b7 3.00 km \u00b7 10.0 min \u00b7 " +
                       std::to_string(rs::kNormalSeconds + 1) + " samples"),
            std::string::npos);
  EXPECT_EQ(occurrences(series_d(r.out, "speed"), "M"), 1u);
  EXPECT_FALSE(fs::exists(dir_.path() / "-"));
  // No fix during this ride: no map, a note.
  EXPECT_EQ(occurrences(r.out, ">no GNSS track for this ride</text>"), 1u);
  EXPECT_EQ(r.out.find("panel-map"), std::string::npos);
  EXPECT_EQ(r.err, "");
}

TEST_F(RidePlotCli, DamagedTrackIsLeftOutWithAWarningNamingTheRide) {
  {
    // Past the Store, which refuses such tracks: a damaged or edited file.
    storage::Database raw(db_.string());
    raw.exec("UPDATE rides SET track = '[[13.4,52.5],[13.5' WHERE ride_id = 'ride-normal'");
    raw.exec("UPDATE rides SET track = '[[13.4,52.5],[\"x\",1]]' WHERE ride_id <> 'ride-normal'");
  }
  const Result normal = plot({"ride-normal", "--db", db_.string(), "--out", svg_.string()});
  ASSERT_EQ(normal.code, 0) << normal.err;
  EXPECT_EQ(normal.err,
            "fleetgw ride plot: ride 'ride-normal': track: not valid JSON; plotted without it\n");
  std::string svg = read_text_file(svg_);
  EXPECT_EQ(svg.find("panel-map"), std::string::npos);
  EXPECT_EQ(occurrences(svg, ">no GNSS track for this ride</text>"), 1u);
  EXPECT_TRUE(svg.ends_with("</svg>\n"));

  const Result latest = plot({"latest", "--db", db_.string(), "--out", svg_.string()});
  ASSERT_EQ(latest.code, 0) << latest.err;
  EXPECT_EQ(occurrences(latest.err, "\n"), 1u) << "the hostile id broke the line: " << latest.err;
  EXPECT_NE(latest.err.find("ride '<script>alert(\"x\")</script> & 'q' \\x1b[2J\\nnext"),
            std::string::npos)
      << latest.err;
  EXPECT_NE(latest.err.find("': track: position 1: not an array of two numbers"), std::string::npos)
      << latest.err;
  svg = read_text_file(svg_);
  EXPECT_EQ(svg.find("panel-map"), std::string::npos);
  EXPECT_EQ(occurrences(svg, ">no GNSS track for this ride</text>"), 1u);
}

TEST_F(RidePlotCli, UnknownRideExitsOneNamingItAndTheStore) {
  const Result r = plot({"no-such\nride", "--db", db_.string(), "--out", svg_.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no ride 'no-such\\nride' in " + db_.string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(svg_));

  const fs::path empty = dir_.path() / "empty.db";
  {
    storage::StoreOptions o;
    o.path = empty.string();
    storage::Store store(o);
  }
  const Result none = plot({"latest", "--db", empty.string(), "--out", svg_.string()});
  EXPECT_EQ(none.code, 1);
  EXPECT_NE(none.err.find("no rides in " + empty.string()), std::string::npos) << none.err;
}

TEST_F(RidePlotCli, NotAStoreExitsTwo) {
  const Result missing =
      plot({"latest", "--db", (dir_.path() / "missing.db").string(), "--out", svg_.string()});
  EXPECT_EQ(missing.code, 2) << missing.err;
  EXPECT_NE(missing.err.find("missing.db"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(dir_.path() / "missing.db"));
}

TEST_F(RidePlotCli, UsageErrorsExitTwo) {
  EXPECT_EQ(plot({"latest", "--db", db_.string()}).code, 2);                // no --out
  EXPECT_EQ(plot({"--db", db_.string(), "--out", svg_.string()}).code, 2);  // no RIDE_ID
  EXPECT_EQ(plot({"latest", "--out", svg_.string(), "--bogus"}).code, 2);
  EXPECT_EQ(run({FLEETGW_BIN, "ride"}, dir_.path()).code, 2);  // no subcommand
  const Result help = run({FLEETGW_BIN, "ride", "plot", "--help"}, dir_.path());
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(help.out.find("--out"), std::string::npos);
  EXPECT_FALSE(fs::exists(svg_));
}

TEST_F(RidePlotCli, UnwritableOutputExitsOne) {
  const fs::path out = dir_.path() / "no-such-dir" / "ride.svg";
  const Result r = plot({"latest", "--db", db_.string(), "--out", out.string()});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("cannot write '" + out.string() + "'"), std::string::npos) << r.err;
}

TEST_F(RidePlotCli, StoreAndAssistNamesFromTheConfiguration) {
  const fs::path cfg = dir_.path() / "fleetgw.toml";
  write_text_file(cfg, "[storage]\npath = \"" + db_.string() +
                           "\"\n[protocol.assist_names]\n0x02 = \"boost\"\n");
  const Result r = plot({"ride-normal", "--config", cfg.string(), "--out", svg_.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string svg = read_text_file(svg_);
  EXPECT_NE(svg.find("<title>Ride ride-normal</title>"), std::string::npos);
  EXPECT_NE(svg.find(">boost</text>"), std::string::npos);  // the configured U7 name
  EXPECT_EQ(svg.find(">norm</text>"), std::string::npos);
}

}  // namespace
}  // namespace fleetgw::testing::ride_plot_cli
