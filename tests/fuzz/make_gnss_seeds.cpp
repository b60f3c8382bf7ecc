// Writes a seed corpus for fuzz_gnss_stream into the folder given as the only argument: M8T streams
// mixing UBX frames (NAV-PVT with and without a fix, ACK/NAK, the CFG frames hardware.md lists) and
// NMEA sentences (hardware.md's GNGGA, a no-fix GGA, RMC, TXT), plus noise and a cut-off sentence.
// The first byte of each seed is the harness's chunking selector. Generated at test time; never
// committed.

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "corpus_dir.hpp"
#include "hwr/hal/hw/ubx_protocol.hpp"

namespace {

using Bytes = std::vector<uint8_t>;

Bytes text(const std::string& s) { return Bytes(s.begin(), s.end()); }

void put_le(Bytes* p, size_t off, uint32_t v, int n) {
  for (int i = 0; i < n; ++i) (*p)[off + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}

Bytes nav_pvt(bool fix_ok) {
  Bytes p(92, 0);
  put_le(&p, 0, 123456789u, 4);
  put_le(&p, 4, 2024, 2);
  p[6] = 5;
  p[7] = 17;
  p[11] = 0x07;
  p[20] = fix_ok ? 3 : 0;
  p[21] = fix_ok ? 0x01 : 0x00;
  p[23] = 14;
  put_le(&p, 24, 103409595u, 4);
  put_le(&p, 28, 633744733u, 4);
  put_le(&p, 32, 207100u, 4);
  put_le(&p, 36, 167000u, 4);
  put_le(&p, 40, 1500u, 4);
  put_le(&p, 44, 2500u, 4);
  put_le(&p, 76, 156u, 2);
  return hwr::hal::hw::make_ubx_frame(0x01, 0x07, p.data(), p.size());
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (const int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  using namespace hwr::hal::hw;
  const Bytes gga = text("$GNGGA,173002.00,6322.46840,N,01020.45757,E,1,05,7.83,167.0,M,40.1,M,,*45\r\n");
  const Bytes gga_nofix = text("$GNGGA,173003.00,,,,,0,00,99.99,,,,,,*7E\r\n");
  const Bytes txt = text("$GNTXT,01,01,02,ANTSTATUS=INIT*3B\r\n");
  const uint8_t rate_id[2] = {0x06, 0x08};
  const Bytes ack = make_ubx_frame(0x05, 0x01, rate_id, 2);
  const Bytes nak = make_ubx_frame(0x05, 0x00, rate_id, 2);
  const Bytes cfg_rate = make_cfg_rate(100);
  const Bytes cfg_msg = make_cfg_msg(0x01, 0x07, 1);
  const Bytes noise = {0x00, 0xB5, 0x13, '$', 'G', 0xB5, 0x62, 0xFF, 0xFF};

  std::vector<Bytes> seeds;
  auto seed = [&](uint8_t chunking, std::initializer_list<Bytes> parts) {
    Bytes s = {chunking};
    for (const Bytes& p : parts) s.insert(s.end(), p.begin(), p.end());
    seeds.push_back(s);
  };
  seed(0, {gga});
  seed(0, {nav_pvt(true)});
  seed(1, {gga, nav_pvt(true), ack, txt, nak});
  seed(9, {noise, gga_nofix, noise, nav_pvt(false), noise});
  seed(4, {cfg_rate, cfg_msg, ack, ack});
  seed(0, {text("$GNGGA,173002.00,6322.4"), ack, gga});  // a sentence cut off by a frame
  const Bytes pvt = nav_pvt(true);
  seed(2, {Bytes(pvt.begin(), pvt.begin() + 40), gga, txt});  // a frame cut short
  int written = 0;
  for (const Bytes& s : seeds) {
    const std::string path = dir + "/seed_gnss_" + std::to_string(written) + ".bin";
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr || std::fwrite(s.data(), 1, s.size(), f) != s.size() || std::fclose(f) != 0) {
      std::fprintf(stderr, "cannot write %s\n", path.c_str());
      return 1;
    }
    ++written;
  }
  std::printf("wrote %d GNSS seed streams to %s\n", written, dir.c_str());
  return 0;
}
