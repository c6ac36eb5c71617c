// fleetgw-fleet-sim (fleet_sim_options.h): the options, the shard processes, the merged report.
#include <mosquitto.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "backend/fleet_sim/fleet_sim_options.h"
#include "backend/fleet_sim/sim_shard.h"

namespace fleetgw::fleet_sim {

void add_fleet_sim_options(CLI::App& app, FleetSimOptions& o) {
  app.add_option("--vehicles", o.vehicles, "number of simulated vehicles")
      ->check(CLI::Range(1, 200000))
      ->capture_default_str();
  app.add_option("--broker", o.broker, "broker URI (tcp://HOST:PORT or mqtt://HOST:PORT)")
      ->capture_default_str();
  app.add_option("--topic-prefix", o.topic_prefix, "topic prefix")->capture_default_str();
  app.add_option("--id-prefix", o.id_prefix, "vehicle ids are PREFIX<index>")
      ->capture_default_str();
  app.add_option("--first-index", o.first_index,
                 "index of the first vehicle (to split a fleet over runs)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--duration-s", o.duration_s, "run this long (real time)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--riding-share", o.riding_share, "share of the fleet riding (the rest parked)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--seed", o.seed, "seed of the simulated values")->capture_default_str();
  app.add_option("--processes", o.processes,
                 "event-loop processes (0: one per 5,000 vehicles, at least one)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  app.add_option("--connect-rate", o.connect_rate, "new sessions per second over the fleet")
      ->check(CLI::Range(1.0, 100000.0))
      ->capture_default_str();
  app.add_option("--source-addresses", o.source_addresses,
                 "connect vehicle i from 127.0.0.(2 + (first-index + i) % K) (-1: one address per "
                 "5,000 vehicles of first-index + vehicles when the broker is on 127.x, else 0: "
                 "the kernel's choice)")
      ->check(CLI::Range(-1, 250))
      ->capture_default_str();
  app.add_option("--keepalive-s", o.keepalive_s, "MQTT keep-alive (the gateway's mqtt.keepalive_s)")
      ->check(CLI::Range(5, 3600))
      ->capture_default_str();
  app.add_option("--stop-timeout-s", o.stop_timeout_s,
                 "after the run or a signal: how long to wait for the last PUBACKs")
      ->check(CLI::Range(0.0, 600.0))
      ->capture_default_str();
  app.add_option("--report", o.report, "write the JSON report to this file instead of stdout");
}

namespace {

// tcp://host:port, mqtt://host:port, host:port or host; TLS is not simulated.
bool parse_broker(const std::string& uri, std::string& host, int& port, std::string& error) {
  std::string rest = uri;
  const auto scheme_end = rest.find("://");
  if (scheme_end != std::string::npos) {
    const std::string scheme = rest.substr(0, scheme_end);
    if (scheme != "tcp" && scheme != "mqtt") {
      error =
          "--broker '" + uri + "': scheme '" + scheme + "' is not supported (tcp:// or mqtt://)";
      return false;
    }
    rest = rest.substr(scheme_end + 3);
  }
  const auto colon = rest.rfind(':');
  host = rest.substr(0, colon);
  port = 1883;
  if (colon != std::string::npos) {
    try {
      std::size_t used = 0;
      port = std::stoi(rest.substr(colon + 1), &used);
      if (used != rest.size() - colon - 1 || port < 1 || port > 65535) throw std::out_of_range("");
    } catch (const std::exception&) {
      error = "--broker '" + uri + "': the port must be a number 1..65535";
      return false;
    }
  }
  if (host.empty()) {
    error = "--broker '" + uri + "': no host";
    return false;
  }
  return true;
}

struct FileClose {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileClose>;

struct ShardProcess {
  pid_t pid = -1;
  File report;
  bool done = false;
  bool ok = false;
};

// The child: its shard, its report into `out` (a file the parent reads after the exit).
[[noreturn]] void run_child(const ShardPlan& plan, std::FILE* out, pid_t parent) {
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);  // an orphaned shard stops as if signalled
  if (::getppid() != parent) ::_exit(3);
  int status = 1;
  try {
    mosquitto_lib_init();
    const std::string text = run_shard(plan).dump();
    mosquitto_lib_cleanup();
    status = std::fwrite(text.data(), 1, text.size(), out) == text.size() && std::fflush(out) == 0
                 ? 0
                 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fleet-sim[%d]: %s\n", plan.shard, e.what());
  }
  // Not exit(): the parent's atexit handlers and stdio buffers belong to the parent.
  ::_exit(status);
}

nlohmann::json merge(std::vector<ShardProcess>& shards, int& failed) {
  nlohmann::json total = {{"messages", 0},
                          {"records", 0},
                          {"payload_bytes", 0},
                          {"riding_packet_bytes", 0},
                          {"parked_packet_bytes", 0},
                          {"resent", 0},
                          {"refused", 0},
                          {"unrouted", 0},
                          {"disconnects", 0},
                          {"connect_failures", 0},
                          {"stale_acks", 0},
                          {"unacknowledged", 0},
                          {"connected", 0},
                          {"last_connack_s", 0.0}};
  nlohmann::json stores = nlohmann::json::array();
  for (ShardProcess& s : shards) {
    nlohmann::json r;
    if (s.ok) {
      std::rewind(s.report.get());
      std::string text;
      std::array<char, 65536> buf{};
      std::size_t n;
      while ((n = std::fread(buf.data(), 1, buf.size(), s.report.get())) > 0)
        text.append(buf.data(), n);
      r = nlohmann::json::parse(text, nullptr, false);
    }
    if (!s.ok || r.is_discarded()) {
      ++failed;
      continue;
    }
    for (auto& [key, value] : total.items()) {
      if (key == "last_connack_s") {
        value = std::max(value.get<double>(), r.value(key, 0.0));
      } else {
        value = value.get<std::int64_t>() + r.value(key, std::int64_t{0});
      }
    }
    for (auto& store : r["stores"]) stores.push_back(std::move(store));
  }
  total["stores"] = std::move(stores);
  return total;
}

int run(const FleetSimOptions& o) {
  ShardPlan plan;
  plan.options = o;
  std::string error;
  if (!parse_broker(o.broker, plan.host, plan.port, error)) {
    std::cerr << "fleetgw-fleet-sim: " << error << '\n';
    return 2;
  }
  const int shards = o.processes > 0 ? o.processes : std::max(1, (o.vehicles + 4999) / 5000);
  plan.shards = std::min(shards, o.vehicles);
  plan.source_addresses = o.source_addresses >= 0 ? o.source_addresses
                          : plan.host.rfind("127.", 0) == 0
                              ? std::min(250, (o.first_index + o.vehicles + 4999) / 5000)
                              : 0;
  plan.riding = static_cast<int>(std::lround(o.vehicles * o.riding_share));
  // Three descriptors per session (its socket, and the socket pair libmosquitto makes in
  // mosquitto_new to interrupt its own loop): raise the soft limit to the hard one, check it fits.
  rlimit nofile{};
  ::getrlimit(RLIMIT_NOFILE, &nofile);
  nofile.rlim_cur = nofile.rlim_max;
  ::setrlimit(RLIMIT_NOFILE, &nofile);
  const auto per_shard = static_cast<rlim_t>((o.vehicles + plan.shards - 1) / plan.shards);
  if (3 * per_shard + 64 > nofile.rlim_cur) {
    std::cerr << "fleetgw-fleet-sim: " << per_shard << " sessions per process need "
              << 3 * per_shard + 64 << " file descriptors, the limit is " << nofile.rlim_cur
              << " (ulimit -Hn): use --processes "
              << (3 * static_cast<rlim_t>(o.vehicles) / (nofile.rlim_cur - 64) + 1) << " or more\n";
    return 2;
  }

  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  ::pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);  // the shards take them by signalfd

  plan.start_us = now_us();
  const pid_t self = ::getpid();
  std::vector<ShardProcess> procs(static_cast<std::size_t>(plan.shards));
  std::cout.flush();
  std::fflush(nullptr);
  for (int s = 0; s < plan.shards; ++s) {
    ShardProcess& p = procs[static_cast<std::size_t>(s)];
    p.report.reset(std::tmpfile());
    if (!p.report) {
      std::cerr << "fleetgw-fleet-sim: cannot create a temporary file for a report\n";
      return 1;
    }
    plan.shard = s;
    p.pid = ::fork();
    if (p.pid == 0) run_child(plan, p.report.get(), self);
    if (p.pid < 0) {
      std::cerr << "fleetgw-fleet-sim: fork failed\n";
      return 1;
    }
  }
  std::fprintf(stderr, "fleet-sim: %d vehicles (%d riding) in %d processes, %d source addresses\n",
               o.vehicles, plan.riding, plan.shards, plan.source_addresses);

  // Shards end by themselves after the run and the PUBACK wait; a signal is passed on to them.
  // Whatever happens, nothing outlives kill_at: the promise that SIGTERM is honoured.
  const auto grace = static_cast<std::int64_t>((o.stop_timeout_s + 5) * 1e6);
  std::int64_t kill_at = plan.start_us + static_cast<std::int64_t>(o.duration_s * 1e6) + grace +
                         static_cast<std::int64_t>(o.vehicles / o.connect_rate * 1e6);
  std::size_t running = procs.size();
  while (running > 0) {
    timespec tick{0, 100'000'000};
    if (::sigtimedwait(&stop_signals, nullptr, &tick) > 0) {
      for (const ShardProcess& p : procs) {
        if (!p.done) ::kill(p.pid, SIGTERM);
      }
      kill_at = std::min(kill_at, now_us() + grace);
    }
    for (ShardProcess& p : procs) {
      int status = 0;
      if (!p.done && ::waitpid(p.pid, &status, WNOHANG) == p.pid) {
        p.done = true;
        p.ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
        --running;
      }
    }
    if (running > 0 && now_us() > kill_at) {
      for (const ShardProcess& p : procs) {
        if (!p.done) {
          std::fprintf(stderr, "fleet-sim: process %d did not stop in time: killed\n", p.pid);
          ::kill(p.pid, SIGKILL);
        }
      }
      kill_at = INT64_MAX;  // reaped on the next turns
    }
  }

  int failed = 0;
  nlohmann::json report = merge(procs, failed);
  report["vehicles"] = o.vehicles;
  report["riding"] = plan.riding;
  report["processes"] = plan.shards;
  report["failed_processes"] = failed;
  report["duration_s"] = static_cast<double>(now_us() - plan.start_us) / 1e6;
  const std::string text = report.dump();
  if (o.report.empty()) {
    std::cout << text << std::endl;
  } else {
    const std::string tmp = o.report + ".tmp";
    std::ofstream(tmp) << text << '\n';
    std::filesystem::rename(tmp, o.report);
  }
  std::fprintf(stderr,
               "fleet-sim: %lld of %d connected, %lld messages, %lld records, %lld resent, "
               "%lld unrouted, %lld disconnects, %lld unacknowledged, %d failed processes\n",
               static_cast<long long>(report["connected"].get<std::int64_t>()), o.vehicles,
               static_cast<long long>(report["messages"].get<std::int64_t>()),
               static_cast<long long>(report["records"].get<std::int64_t>()),
               static_cast<long long>(report["resent"].get<std::int64_t>()),
               static_cast<long long>(report["unrouted"].get<std::int64_t>()),
               static_cast<long long>(report["disconnects"].get<std::int64_t>()),
               static_cast<long long>(report["unacknowledged"].get<std::int64_t>()), failed);
  const bool all = report["connected"].get<std::int64_t>() == o.vehicles &&
                   report["unacknowledged"].get<std::int64_t>() == 0 && failed == 0;
  return all ? 0 : 1;
}

}  // namespace
}  // namespace fleetgw::fleet_sim

int main(int argc, char** argv) {
  CLI::App app{
      "fleetgw fleet-sim: N simulated vehicles, each its own MQTT 5 session, against a broker "
      "(docs/backend.md)"};
  fleetgw::fleet_sim::FleetSimOptions options;
  fleetgw::fleet_sim::add_fleet_sim_options(app, options);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    return fleetgw::fleet_sim::run(options);
  } catch (const std::exception& e) {
    std::cerr << "fleetgw fleet-sim: " << e.what() << '\n';
    return 1;
  }
}
