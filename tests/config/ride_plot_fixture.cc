// ride_plot_fixture STORE: writes the `fleetgw ride plot` test store (ride_plot_store.h) for
// the Chromium rendering test (render_ride_plot.py).
#include <exception>
#include <iostream>

#include "tests/config/ride_plot_store.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: ride_plot_fixture STORE\n";
    return 2;
  }
  try {
    fleetgw::testing::ride_plot_store::write_ride_store(argv[1]);
  } catch (const std::exception& e) {
    std::cerr << "ride_plot_fixture: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
