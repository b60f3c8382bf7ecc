// Writes a seed corpus for fuzz_zed_inputs into the folder given as the only argument: HID reports
// (selector byte 0) with frame sync, a new magnetometer reading and "not valid" temperatures, and a
// calibration file (selector byte 5: eye width 1280) that parses. Generated at test time.

#include <cstdio>
#include <string>
#include <vector>

#include "corpus_dir.hpp"

namespace {

bool write(const std::string& path, const std::vector<uint8_t>& bytes) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  return std::fclose(f) == 0 && ok;
}

std::vector<uint8_t> report(uint8_t sync, uint8_t mag_state, int16_t temp) {
  std::vector<uint8_t> r(1 + 64, 0);
  r[0] = 0;  // selector: report
  uint8_t* b = r.data() + 1;
  b[0] = 0x01;
  b[2] = 0x40;
  b[3] = 0x42;
  b[10] = 0x10;
  b[21] = 0x10;  // accel z = 4096 counts = 1 g
  b[22] = sync;
  b[24] = 7;
  b[28] = static_cast<uint8_t>(temp & 0xFF);
  b[29] = static_cast<uint8_t>(static_cast<uint16_t>(temp) >> 8);
  b[30] = mag_state;
  b[31] = 0x90;
  b[32] = 0x01;
  return r;
}

const char* kConf =
    "[LEFT_CAM_HD]\nfx=532.41\nfy=532.535\ncx=636.025\ncy=362.4065\nk1=-0.0634518\nk2=0.0401532\n"
    "p1=-0.000273455\np2=0.00064619\nk3=-0.0167323\n\n"
    "[RIGHT_CAM_HD]\nfx=531.9\nfy=532.04\ncx=641.38\ncy=358.75\nk1=-0.0587\nk2=0.0330\np1=0.00021\n"
    "p2=-0.00035\nk3=-0.0121\n\n"
    "[STEREO]\nBaseline=119.907\nTY_HD=0.0242\nTZ_HD=-0.4305\nCV_HD=0.0034\nRX_HD=-0.0012\nRZ_HD=0.0008\n";

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  bool ok = write(dir + "/report_plain", report(0, 0, 2500));
  ok = write(dir + "/report_sync_mag", report(1, 2, -27315)) && ok;
  const std::string conf(kConf);
  std::vector<uint8_t> c = {5};  // selector: calibration at eye width 1280
  c.insert(c.end(), conf.begin(), conf.end());
  ok = write(dir + "/conf_hd", c) && ok;
  if (!ok) {
    std::fprintf(stderr, "make_zed_seeds: cannot write into %s\n", dir.c_str());
    return 1;
  }
  return 0;
}
