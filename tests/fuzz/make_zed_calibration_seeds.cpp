// Writes a seed corpus for fuzz_zed_calibration into the folder given as the only argument: a
// realistic ZED 2i SN<serial>.conf (all four resolutions) behind each eye-width selector byte
// (0 2K, 1 FHD, 2 HD, 3 VGA, 4 none), the same file with CRLF line ends, comments and odd spacing,
// and a minimal HD-only file without p1 p2 k3 and with plain TY / TZ. Generated at test time.

#include <cstdint>
#include <cstdio>
#include <string>

#include "corpus_dir.hpp"

namespace {

bool write(const std::string& path, uint8_t selector, const std::string& text) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  bool ok = std::fputc(selector, f) != EOF;
  ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() && ok;
  return std::fclose(f) == 0 && ok;
}

std::string camera(const char* section, double fx, double cx, double cy, bool left) {
  const char* dist = left
                         ? "k1=-0.0411857\nk2=0.00963207\np1=-0.000322616\np2=0.000204186\nk3=-0.00519314\n"
                         : "k1=-0.0406893\nk2=0.00927831\np1=-0.000185236\np2=-0.000437622\nk3=-0.00490219\n";
  return std::string("[") + section + "]\nfx=" + std::to_string(fx) + "\nfy=" + std::to_string(fx * 0.9998) +
         "\ncx=" + std::to_string(cx) + "\ncy=" + std::to_string(cy) + "\n" + dist + "\n";
}

std::string full_conf() {
  std::string s;
  s += camera("LEFT_CAM_2K", 1059.73, 1108.11, 630.67, true) +
       camera("RIGHT_CAM_2K", 1061.36, 1125.48, 622.985, false);
  s += camera("LEFT_CAM_FHD", 1059.73, 964.11, 549.67, true) +
       camera("RIGHT_CAM_FHD", 1061.36, 981.48, 541.985, false);
  s += camera("LEFT_CAM_HD", 529.865, 644.055, 360.335, true) +
       camera("RIGHT_CAM_HD", 530.68, 652.74, 356.4925, false);
  s += camera("LEFT_CAM_VGA", 264.9325, 338.0275, 187.6675, true) +
       camera("RIGHT_CAM_VGA", 265.34, 342.37, 185.74625, false);
  s += "[STEREO]\nBaseline=119.987\n";
  for (const char* r : {"2K", "FHD", "HD", "VGA"}) {
    s += std::string("TY_") + r + "=0.0291\nTZ_" + r + "=-0.3456\nCV_" + r + "=0.00421\nRX_" + r +
         "=0.00171\nRZ_" + r + "=-0.00093\n";
  }
  s += "\n[MISC]\nSensor_ID=1\n";
  return s;
}

std::string crlf_and_comments(const std::string& text) {
  std::string out = "; ZED 2i factory calibration\r\n# SN12345\r\n\r\n";
  for (char c : text) {
    if (c == '=') {
      out += " = ";
    } else if (c == '\n') {
      out += "\r\n";
    } else {
      out += c;
    }
  }
  return out;
}

const char* kMinimalHd =
    "[left_cam_hd]\nfx=529.865\nfy=529.76\ncx=644.055\ncy=360.335\nk1=-0.04\nk2=0.0096\n"
    "[right_cam_hd]\nfx=530.68\nfy=530.545\ncx=652.74\ncy=356.49\nk1=-0.04\nk2=0.0093\n"
    "[stereo]\nbaseline=120\nty=0.03\ntz=-0.35\nrx_hd=0.0017\ncv_hd=0.0042\nrz_hd=-0.0009\n";

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  const std::string conf = full_conf();
  bool ok = true;
  for (uint8_t selector = 0; selector < 5; ++selector) {
    ok = write(dir + "/conf_" + std::to_string(selector), selector, conf) && ok;
  }
  ok = write(dir + "/conf_crlf_fhd", 1, crlf_and_comments(conf)) && ok;
  ok = write(dir + "/minimal_hd", 2, kMinimalHd) && ok;
  if (!ok) {
    std::fprintf(stderr, "make_zed_calibration_seeds: cannot write into %s\n", dir.c_str());
    return 1;
  }
  return 0;
}
