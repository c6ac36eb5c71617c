#include <malloc.h>

#include "gateway/cli/cli.h"
#include "gateway/cli/protobuf_log.h"

namespace {

// Oversized MQTT messages must not pile up in memory (issue 11, item 8).
//
// glibc serves blocks above M_MMAP_THRESHOLD (128 KiB) with their own mmap, returned to the
// kernel on free. By default that threshold is dynamic: freeing such a block raises it to the
// block's size, so after one 20 MB message the next 20 MB copy of a payload (Paho C++'s message)
// came from the heap and stayed there: measured 31.8 -> 72.8 MB after a second 20 MB message on
// the cmd topic. Setting the thresholds explicitly turns that adjustment off, so large payloads
// always get their own mapping and leave nothing behind; trimming at 1 MiB keeps the top of the
// heap from holding freed memory. Only blocks above 256 KiB pay a mmap/munmap; the gateway's hot
// path allocates nothing that large.
//
// What this cannot release: Paho C (1.3.12) keeps its socket receive buffer at the size of the
// largest packet ever received, for the life of the process (one payload-sized buffer, 20 MB
// after a 20 MB message). Only not receiving such packets bounds that: the broker's
// message_size_limit, or an MQTT 5 maximum packet size in CONNECT (docs/deployment.md).
void bound_retained_heap() {
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
  mallopt(M_TRIM_THRESHOLD, 1024 * 1024);
}

}  // namespace

int main(int argc, char** argv) {
  bound_retained_heap();
  // Hostile payloads must not write one stderr line each through protobuf (issue 11).
  const fleetgw::cli::ProtobufLogRoute protobuf_log;
  return fleetgw::cli::run_cli(argc, argv);
}
