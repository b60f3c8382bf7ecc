#include "hwr/recon/plate_fit.hpp"

#include "plate_edge_rays.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>
#include <unordered_set>
#include <cstdio>

#include <Eigen/Eigenvalues>

#include "hwr/core/config.hpp"
#include "hwr/core/file_io.hpp"

namespace hwr::recon {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------------------------
// Ground truth

// The seams' `plates: ["a", "b"]` is a list of text, which core::ConfigMap does not read; the value
// is taken from the seam's own lines of the text (between its first line and the next seam's).
// Returns false with *problem set when the value is not a flow list of names.
bool parse_name_list(const std::string& value, std::vector<std::string>* names, std::string* problem) {
  std::string v = value;
  const size_t hash = v.find(" #");
  if (hash != std::string::npos && v.find('"', hash) == std::string::npos) v.resize(hash);
  while (!v.empty() && std::isspace(static_cast<unsigned char>(v.back()))) v.pop_back();
  size_t i = 0;
  while (i < v.size() && std::isspace(static_cast<unsigned char>(v[i]))) ++i;
  if (i >= v.size() || v[i] != '[' || v.back() != ']') {
    *problem = "expected a list of plate names like [\"a\", \"b\"], got '" + value + "'";
    return false;
  }
  const std::string body = v.substr(i + 1, v.size() - i - 2);
  size_t k = 0;
  auto skip_space = [&]() {
    while (k < body.size() && std::isspace(static_cast<unsigned char>(body[k]))) ++k;
  };
  skip_space();
  while (k < body.size()) {
    std::string name;
    if (body[k] == '"') {
      ++k;
      bool closed = false;
      while (k < body.size()) {
        const char c = body[k++];
        if (c == '\\' && k < body.size()) {
          name += body[k++];
        } else if (c == '"') {
          closed = true;
          break;
        } else {
          name += c;
        }
      }
      if (!closed) {
        *problem = "unterminated quoted name in '" + value + "'";
        return false;
      }
    } else {
      while (k < body.size() && body[k] != ',') name += body[k++];
      while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) name.pop_back();
    }
    names->push_back(name);
    skip_space();
    if (k < body.size()) {
      if (body[k] != ',') {
        *problem = "expected ',' between plate names in '" + value + "'";
        return false;
      }
      ++k;
      skip_space();
    }
  }
  return true;
}

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

// Finds "plates:" among lines [first, last) (1-based, last exclusive) at deeper indentation than
// none; returns its value text, or false when absent.
bool find_plates_line(const std::vector<std::string>& lines, int first, int last, std::string* value) {
  for (int l = std::max(first, 1); l < last && l <= static_cast<int>(lines.size()); ++l) {
    const std::string& s = lines[static_cast<size_t>(l - 1)];
    size_t i = 0;
    while (i < s.size() && (s[i] == ' ' || s[i] == '-')) ++i;
    if (s.compare(i, 7, "plates:") == 0) {
      *value = s.substr(i + 7);
      return true;
    }
  }
  return false;
}

bool all_finite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

void read_plate(core::ConfigMap& m, PlateTruth* p) {
  std::vector<double> size, T16, corners;
  m.require("name", &p->name)
      .require("size_m", &size)
      .require("T_world_plate", &T16)
      .require("corners_world", &corners);
  if (m.has("size_m") && size.size() != 3) {
    if (!size.empty())
      m.record_error("size_m",
                     "expected 3 numbers (length, width, thickness), got " + std::to_string(size.size()));
    return;
  }
  if (size.size() == 3) {
    if (!all_finite(size) || size[0] <= 0 || size[1] <= 0 || size[2] <= 0) {
      m.record_error("size_m", "length, width and thickness must be positive finite metres");
      return;
    }
    p->size_m = Eigen::Vector3d(size[0], size[1], size[2]);
  }
  if (T16.size() != 16) {
    if (m.has("T_world_plate")) m.record_error("T_world_plate", "expected 16 numbers (4x4 row-major)");
    return;
  }
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = T16[static_cast<size_t>(4 * r + c)];
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  if (!all_finite(T16) || (T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9 ||
      (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0) {
    m.record_error("T_world_plate", "not a rigid transform (orthonormal rotation, last row 0 0 0 1)");
    return;
  }
  p->T_world_plate.linear() = R;
  p->T_world_plate.translation() = T.topRightCorner<3, 1>();
  if (corners.size() != 24) {
    if (m.has("corners_world")) m.record_error("corners_world", "expected 24 numbers (8 corners x, y, z)");
    return;
  }
  for (int i = 0; i < 8; ++i) {
    p->corners_world[static_cast<size_t>(i)] =
        Eigen::Vector3d(corners[static_cast<size_t>(3 * i)], corners[static_cast<size_t>(3 * i + 1)],
                        corners[static_cast<size_t>(3 * i + 2)]);
    const Eigen::Vector3d local(((i >> 2) & 1 ? 0.5 : -0.5) * p->size_m.x(),
                                ((i >> 1) & 1 ? 0.5 : -0.5) * p->size_m.y(),
                                (i & 1 ? 0.5 : -0.5) * p->size_m.z());
    const double err = (p->T_world_plate * local - p->corners_world[static_cast<size_t>(i)]).norm();
    if (!(err <= 1e-3)) {
      m.record_error("corners_world", "corner " + std::to_string(i) + " is " + std::to_string(err * 1e3) +
                                          " mm from the one T_world_plate and size_m give");
      return;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Cloud file

uint32_t load_u32_le(const unsigned char* b) {
  return static_cast<uint32_t>(b[0]) | (static_cast<uint32_t>(b[1]) << 8) |
         (static_cast<uint32_t>(b[2]) << 16) | (static_cast<uint32_t>(b[3]) << 24);
}

float load_f32_le(const unsigned char* b) {
  const uint32_t u = load_u32_le(b);
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

void store_f32_le(float f, unsigned char* b) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  for (int i = 0; i < 4; ++i) b[i] = static_cast<unsigned char>((u >> (8 * i)) & 0xFF);
}

// ---------------------------------------------------------------------------------------------
// Plate fit: geometry helpers

using Vec2 = Eigen::Vector2d;

// A convex polygon in the plane (at most 6 vertices for a plane cutting a cube, 7 after one clip).
struct Polygon {
  int n = 0;
  std::array<Vec2, 8> v{};
};

// Area and centroid (shoelace). Area 0: centroid is the vertex mean.
void area_centroid(const Polygon& p, double* area, Vec2* centroid) {
  double a2 = 0;
  Vec2 c = Vec2::Zero();
  for (int i = 0; i < p.n; ++i) {
    const Vec2& p0 = p.v[static_cast<size_t>(i)];
    const Vec2& p1 = p.v[static_cast<size_t>((i + 1) % p.n)];
    const double cross = p0.x() * p1.y() - p1.x() * p0.y();
    a2 += cross;
    c += (p0 + p1) * cross;
  }
  if (std::fabs(a2) < 1e-18) {
    c.setZero();
    for (int i = 0; i < p.n; ++i) c += p.v[static_cast<size_t>(i)];
    *centroid = p.n > 0 ? Vec2(c / p.n) : Vec2::Zero();
    *area = 0;
    return;
  }
  *area = 0.5 * std::fabs(a2);
  *centroid = c / (3.0 * a2);
}

// The part of p with n2 . x <= d (Sutherland-Hodgman, one half-plane).
Polygon clip(const Polygon& p, const Vec2& n2, double d) {
  Polygon out;
  for (int i = 0; i < p.n; ++i) {
    const Vec2& a = p.v[static_cast<size_t>(i)];
    const Vec2& b = p.v[static_cast<size_t>((i + 1) % p.n)];
    const double sa = n2.dot(a) - d;
    const double sb = n2.dot(b) - d;
    if (sa <= 0 && out.n < 8) out.v[static_cast<size_t>(out.n++)] = a;
    if (((sa < 0 && sb > 0) || (sa > 0 && sb < 0)) && out.n < 8)
      out.v[static_cast<size_t>(out.n++)] = a + (b - a) * (sa / (sa - sb));
  }
  return out;
}

// One voxel mean of the face in its grid cell: the cell's cross section with the plane parallel to
// the face through the mean, in face coordinates (u, w), and the cell's extent [h_lo, h_hi] along the
// face normal on the line through the mean.
struct VoxelCell {
  Polygon section;
  double h_obs = 0;  // the mean's height above the face
  double h_lo = 0, h_hi = 0;
};

bool voxel_cell(const Eigen::Vector3d& p_world, const Eigen::Isometry3d& T_grid_world,
                const Eigen::Isometry3d& T_world_grid, double voxel_m, const Eigen::Vector3d& o_face,
                const Eigen::Vector3d& e_u, const Eigen::Vector3d& e_w, const Eigen::Vector3d& n,
                VoxelCell* out) {
  const Eigen::Vector3d p_grid = T_grid_world * p_world;
  const Eigen::Vector3d lo = (p_grid / voxel_m).array().floor().matrix() * voxel_m;
  out->h_obs = n.dot(p_world - o_face);
  // Extent along n (slab method, grid frame) of the line through the mean's foot on the face.
  const Eigen::Vector3d foot = T_grid_world * (p_world - out->h_obs * n);
  const Eigen::Vector3d dir = T_grid_world.linear() * n;
  double l0 = -1e300, l1 = 1e300;
  for (int i = 0; i < 3; ++i) {
    if (std::fabs(dir[i]) < 1e-12) continue;
    double a = (lo[i] - foot[i]) / dir[i], b = (lo[i] + voxel_m - foot[i]) / dir[i];
    if (a > b) std::swap(a, b);
    l0 = std::max(l0, a), l1 = std::min(l1, b);
  }
  out->h_lo = std::min(l0, out->h_obs);
  out->h_hi = std::max(l1, out->h_obs);
  // Section at the mean's height: where the cell's points are (a face nearly parallel to a cell wall
  // cuts only a sliver of the cell at the wall).
  const double margin = 0.01 * voxel_m;
  const double h_cut = std::clamp(out->h_obs, out->h_lo + margin, out->h_hi - margin);
  Eigen::Vector3d cf[8];  // cube corners in face coordinates (u, w, h - h_cut)
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c_grid = lo + voxel_m * Eigen::Vector3d(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    const Eigen::Vector3d d = T_world_grid * c_grid - o_face;
    cf[i] = Eigen::Vector3d(e_u.dot(d), e_w.dot(d), n.dot(d) - h_cut);
  }
  static constexpr int kEdges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                        {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  std::array<Vec2, 12> pts;
  int np = 0;
  for (const auto& e : kEdges) {
    const Eigen::Vector3d& a = cf[e[0]];
    const Eigen::Vector3d& b = cf[e[1]];
    if ((a.z() <= 0 && b.z() >= 0) || (a.z() >= 0 && b.z() <= 0)) {
      const double dz = a.z() - b.z();
      const double t = std::fabs(dz) < 1e-15 ? 0.0 : a.z() / dz;
      const Vec2 q = (a + (b - a) * t).head<2>();
      bool dup = false;
      for (int k = 0; k < np; ++k) dup = dup || (pts[static_cast<size_t>(k)] - q).squaredNorm() < 1e-16;
      if (!dup) pts[static_cast<size_t>(np++)] = q;
    }
  }
  if (np < 3) return false;
  Vec2 mean = Vec2::Zero();
  for (int k = 0; k < np; ++k) mean += pts[static_cast<size_t>(k)];
  mean /= np;
  std::sort(pts.begin(), pts.begin() + np, [&](const Vec2& a, const Vec2& b) {
    return std::atan2(a.y() - mean.y(), a.x() - mean.x()) < std::atan2(b.y() - mean.y(), b.x() - mean.x());
  });
  out->section.n = std::min(np, 8);
  for (int k = 0; k < out->section.n; ++k)
    out->section.v[static_cast<size_t>(k)] = pts[static_cast<size_t>(k)];
  return true;
}

// Mean of N(0, sigma^2) restricted to [a, b].
double truncated_normal_mean(double sigma, double a, double b) {
  const double za = a / sigma, zb = b / sigma;
  const double pdf_a = std::exp(-0.5 * za * za), pdf_b = std::exp(-0.5 * zb * zb);
  const double mass = 0.5 * (std::erf(zb / std::sqrt(2.0)) - std::erf(za / std::sqrt(2.0)));
  if (mass < 1e-12) return std::fabs(za) < std::fabs(zb) ? a : b;  // far tail: its nearer end
  return sigma * (pdf_a - pdf_b) / (std::sqrt(2.0 * M_PI) * mass);
}

// Fraction w of a boundary voxel's points that lie on a wall at the edge rather than on the face:
// the plate's own side face below the face (h in [-thickness, 0]) or a surface rising from the edge
// (h >= 0), each cut to the cell. The face's points have mean height m_face (noise truncated to the
// cell), a wall's the middle of its span, so the mean's height h_obs = (1 - w) m_face + w m_wall.
double wall_fraction(const VoxelCell& c, double sigma, double thickness) {
  const double m_face = truncated_normal_mean(sigma, c.h_lo, c.h_hi);
  double m_wall = 0;
  if (c.h_obs < m_face) {
    const double a = std::max(c.h_lo, -thickness), b = std::min(c.h_hi, 0.0);
    if (!(b > a)) return 0;
    m_wall = 0.5 * (a + b);
  } else {
    const double a = std::max(c.h_lo, 0.0), b = c.h_hi;
    if (!(b > a)) return 0;
    m_wall = 0.5 * (a + b);
  }
  const double den = m_wall - m_face;
  if (std::fabs(den) < 1e-9) return 0;
  return std::clamp((c.h_obs - m_face) / den, 0.0, 0.95);
}

// The edge offset d (n2 . x = d) for which a fraction 1 - w of the mean lies at the centroid of the
// part of cell section P behind the edge and a fraction w on the wall at the edge itself:
// (1 - w) c(d) + w d = s_obs. Both terms grow monotonically with d, so bisection finds it. A mean at
// or past the full section's value (noise) extrapolates with the aligned square's slope,
// dc/dd = 1/2, so that noise stays symmetric instead of being clamped.
double invert_centroid(const Polygon& P, const Vec2& n2, double s_obs, double w) {
  double s_min = std::numeric_limits<double>::infinity(), s_max = -s_min;
  for (int i = 0; i < P.n; ++i) {
    const double s = n2.dot(P.v[static_cast<size_t>(i)]);
    s_min = std::min(s_min, s);
    s_max = std::max(s_max, s);
  }
  double area = 0;
  Vec2 c;
  area_centroid(P, &area, &c);
  const double f_max = (1 - w) * n2.dot(c) + w * s_max;
  if (s_obs >= f_max) return s_max + (s_obs - f_max) / (0.5 * (1 - w) + w);
  if (s_obs <= s_min) return s_min;
  double lo = s_min, hi = s_max;
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    const Polygon q = clip(P, n2, mid);
    double a = 0;
    Vec2 cq;
    area_centroid(q, &a, &cq);
    const double f = a <= 0 ? mid : (1 - w) * n2.dot(cq) + w * mid;
    if (f < s_obs) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return 0.5 * (lo + hi);
}

// A weight sum reported as a count (PlateFit's point counts): rounded, saturating at INT_MAX.
int rounded_count(double w) {
  return static_cast<int>(std::min(std::round(w), static_cast<double>(std::numeric_limits<int>::max())));
}

struct EdgeSample {
  double t = 0;  // position along the edge
  double d = 0;  // edge offset along its outward normal
  double w = 1;  // weight
};

struct EdgeLine {
  bool ok = false;
  double offset = 0;  // at t = 0
  double slope = 0;   // dd/dt
  int used = 0;       // samples (points: their total weight, rounded)
  double weight = 0;  // total weight of the samples (points: of the points; voxels: their number)
};

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  return v[m];
}

// Weighted least squares d = offset + slope t, refitted twice without samples beyond 3 robust sigmas
// (at least 2 mm). Fewer than 3 samples or a span under 2 cm: slope 0.
EdgeLine fit_edge_line(const std::vector<EdgeSample>& samples, int min_samples) {
  EdgeLine line;
  std::vector<char> keep(samples.size(), 1);
  for (int pass = 0; pass < 3; ++pass) {
    double sw = 0, st = 0, stt = 0, sd = 0, std_ = 0, t_min = 1e300, t_max = -1e300;
    int n = 0;
    for (size_t i = 0; i < samples.size(); ++i) {
      if (!keep[i]) continue;
      const EdgeSample& s = samples[i];
      sw += s.w, st += s.w * s.t, stt += s.w * s.t * s.t, sd += s.w * s.d, std_ += s.w * s.t * s.d;
      t_min = std::min(t_min, s.t), t_max = std::max(t_max, s.t);
      ++n;
    }
    if (n < std::max(1, min_samples) || sw <= 0) {
      line.ok = false;
      line.used = n;
      line.weight = n;
      return line;
    }
    const double det = sw * stt - st * st;
    if (n >= 3 && t_max - t_min >= 0.02 && det > 1e-12 * sw * sw) {
      line.slope = (sw * std_ - st * sd) / det;
      line.offset = (sd - line.slope * st) / sw;
    } else {
      line.slope = 0;
      line.offset = sd / sw;
    }
    line.ok = true;
    line.used = n;
    line.weight = n;
    if (pass == 2) break;
    std::vector<double> abs_r;
    for (size_t i = 0; i < samples.size(); ++i)
      if (keep[i]) abs_r.push_back(std::fabs(samples[i].d - line.offset - line.slope * samples[i].t));
    const double limit = std::max(3.0 * 1.4826 * median_of(abs_r), 0.002);
    for (size_t i = 0; i < samples.size(); ++i)
      keep[i] = std::fabs(samples[i].d - line.offset - line.slope * samples[i].t) <= limit;
  }
  return line;
}

// One face point in the rectangle's frame, with its cell section when the cloud is voxel means.
struct FacePoint {
  Vec2 q;         // face coordinates (u, w), metres
  int cell = -1;  // index into the voxel cells, -1: none
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
};

// The voxel grid of a voxel-mean cloud: cell keys as recon::VoxelMap computes them, and which cells
// hold a face point.
class GridCells {
 public:
  GridCells(const Eigen::Isometry3d& T_world_grid, double voxel_m)
      : T_grid_world_(T_world_grid.inverse(Eigen::Isometry)), inv_voxel_(1.0 / voxel_m) {}
  uint64_t key(const Eigen::Vector3d& p_world) const {
    const Eigen::Vector3d g = T_grid_world_ * p_world * inv_voxel_;
    uint64_t k = 0;
    for (int i = 0; i < 3; ++i) {
      k = (k << 21) | (static_cast<uint64_t>(static_cast<int64_t>(std::floor(g[i]))) & 0x1FFFFF);
    }
    return k;
  }
  void add(const Eigen::Vector3d& p_world) { occupied_.insert(key(p_world)); }
  bool occupied(const Eigen::Vector3d& p_world) const { return occupied_.count(key(p_world)) > 0; }

 private:
  Eigen::Isometry3d T_grid_world_;
  double inv_voxel_;
  std::unordered_set<uint64_t> occupied_;
};

// The four edges: outward normal n2 and tangent t2 = rot90(n2), so that (n2, t2) is right-handed
// for every edge and a rotation phi of the rectangle shows as slope -phi on each of them.
const Vec2 kEdgeNormal[4] = {Vec2(1, 0), Vec2(0, 1), Vec2(-1, 0), Vec2(0, -1)};
const Vec2 kEdgeTangent[4] = {Vec2(0, 1), Vec2(-1, 0), Vec2(0, -1), Vec2(1, 0)};

// Band-mean estimator (header, "Edges"): the points with s in [e - B, e + B_out] and t inside the
// corner margins. Uniform on [e - B, a + b t] in s, they have E[s | t] = (e - B + a + b t) / 2, so the
// least-squares line s = alpha + beta t gives the edge a = 2 alpha - (e - B), b = 2 beta.
// For raw points the band ends early at the first gap past e - B / 2 (kGapBins bins of B / 10 holding
// under a fifth of the band's typical count): a surface a little past the edge (the bench a plate
// thickness below a web's foot) is a separate cluster, and counting it would pull the edge out,
// further each update. (Voxel means come in rows a voxel apart; their face test does this instead.)
// Every count (the histogram, the band's points) and sum is over the points' weights (pw[i] of r[i]).
EdgeLine band_mean_edge(const std::vector<Vec2>& r, const std::vector<double>& pw, int k, double e, double B,
                        double B_out, double half_tangent, double corner_margin, int min_points,
                        bool find_gap) {
  constexpr int kGapBins = 3;
  EdgeLine line;
  const double t_lim = half_tangent - corner_margin;
  if (!(t_lim > 0)) return line;
  const double lo = e - B, bin = 0.1 * B;
  const int n_bins = static_cast<int>(std::ceil((B + B_out) / bin));
  std::vector<double> hist(static_cast<size_t>(n_bins), 0.0);
  for (size_t i = 0; i < r.size(); ++i) {
    const double s = kEdgeNormal[k].dot(r[i]);
    const double t = kEdgeTangent[k].dot(r[i]);
    if (t < -t_lim || t > t_lim || s < lo || s > e + B_out) continue;
    hist[static_cast<size_t>(std::min(n_bins - 1, static_cast<int>((s - lo) / bin)))] += pw[i];
  }
  double hi = e + B_out;
  std::vector<double> inner(hist.begin(), hist.begin() + 5);  // [e - B, e - B / 2)
  std::nth_element(inner.begin(), inner.begin() + 2, inner.end());
  const double level = inner[2];
  if (find_gap && level >= 5) {
    int run = 0;
    for (int i = 5; i < n_bins; ++i) {
      run = (hist[static_cast<size_t>(i)] * 5 < level) ? run + 1 : 0;
      if (run == kGapBins) {
        hi = lo + (i - kGapBins + 1) * bin;
        break;
      }
    }
  }
  // Weighted least squares; (w t) t and (w s) t keep the unweighted sums' rounding when w = 1.
  double n = 0, st = 0, ss = 0, stt = 0, sst = 0, t_min = 1e300, t_max = -1e300;
  for (size_t i = 0; i < r.size(); ++i) {
    const double s = kEdgeNormal[k].dot(r[i]);
    const double t = kEdgeTangent[k].dot(r[i]);
    if (t < -t_lim || t > t_lim || s < lo || s > hi) continue;
    const double w = pw[i], wt = w * t;
    n += w, st += wt, ss += w * s, stt += wt * t, sst += (w * s) * t;
    t_min = std::min(t_min, t), t_max = std::max(t_max, t);
  }
  line.used = rounded_count(n);
  line.weight = n;
  if (n < std::max(min_points, 1)) return line;
  const double var_t = stt / n - (st / n) * (st / n);
  double beta = 0;
  if (n >= 3 && t_max - t_min >= 0.02 && var_t > 1e-12) beta = (sst / n - (st / n) * (ss / n)) / var_t;
  const double alpha = ss / n - beta * st / n;
  line.offset = 2 * alpha - lo;
  line.slope = 2 * beta;
  line.ok = true;
  return line;
}

// Centroid inversion (header, "Edges"): one sample per boundary voxel near the current edge e: a
// voxel whose cell range along the edge normal reaches within a voxel of e, and whose neighbour one
// voxel further out in the face (at the face's height, or half a voxel above or below) holds no face
// point.
void voxel_edge_samples(const std::vector<Vec2>& r, const std::vector<FacePoint>& pts,
                        const std::vector<VoxelCell>& vcells, const std::vector<double>& wall,
                        const GridCells& face_cells, const Vec2& centre, const Eigen::Matrix2d& R,
                        const Eigen::Vector3d& e_u, const Eigen::Vector3d& e_w, const Eigen::Vector3d& n,
                        double voxel_m, int k, double e, double half_tangent, double corner_margin,
                        std::vector<EdgeSample>* out) {
  out->clear();
  const double t_lim = half_tangent - corner_margin;
  if (!(t_lim > 0)) return;
  const Vec2& n2 = kEdgeNormal[k];
  const Vec2 n2_face = R * n2;
  const Eigen::Vector3d step = voxel_m * (n2_face.x() * e_u + n2_face.y() * e_w);
  for (size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].cell < 0) continue;
    const double t = kEdgeTangent[k].dot(r[i]);
    if (t < -t_lim || t > t_lim) continue;
    const Polygon& P_face = vcells[static_cast<size_t>(pts[i].cell)].section;
    Polygon P;
    P.n = P_face.n;
    double s_min = std::numeric_limits<double>::infinity(), s_max = -s_min;
    for (int j = 0; j < P.n; ++j) {
      P.v[static_cast<size_t>(j)] = R.transpose() * (P_face.v[static_cast<size_t>(j)] - centre);
      const double s = n2.dot(P.v[static_cast<size_t>(j)]);
      s_min = std::min(s_min, s);
      s_max = std::max(s_max, s);
    }
    if (s_max < e - voxel_m || s_min > e + voxel_m) continue;
    const Eigen::Vector3d outward = pts[i].p_world + step;
    if (face_cells.occupied(outward) || face_cells.occupied(outward + 0.5 * voxel_m * n) ||
        face_cells.occupied(outward - 0.5 * voxel_m * n))
      continue;
    EdgeSample sample;
    sample.t = t;
    sample.d = invert_centroid(P, n2, n2.dot(r[i]), wall[static_cast<size_t>(pts[i].cell)]);
    out->push_back(sample);
  }
}

// The edge at the outermost point with t inside the corner margins (a restart, biased inward).
EdgeLine outermost_edge(const std::vector<Vec2>& r, const std::vector<double>& pw, int k, double half_tangent,
                        double corner_margin, int min_points) {
  EdgeLine line;
  const double t_lim = half_tangent - corner_margin;
  double s_max = -std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < r.size(); ++i) {
    const double t = kEdgeTangent[k].dot(r[i]);
    if (t < -t_lim || t > t_lim) continue;
    s_max = std::max(s_max, kEdgeNormal[k].dot(r[i]));
    line.weight += pw[i];
  }
  line.used = rounded_count(line.weight);
  line.ok = line.weight >= std::max(min_points, 1);
  line.offset = s_max;
  return line;
}

// The element at index floor(q (n - 1)) of v sorted. With weights w (w[i] the multiplicity of v[i],
// total W): the element at unit-mass position floor(q (W - 1)) of the weight-expanded sorted list, i.e.
// the first sorted element whose cumulative weight exceeds that position: exactly the unweighted
// quantile of v with element i repeated w[i] times, for integer weights.
double quantile(std::vector<double> v, double q, const std::vector<double>* w = nullptr) {
  if (v.empty()) return 0;
  if (w == nullptr) {
    const size_t k = static_cast<size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
  }
  std::vector<size_t> order(v.size());
  double total = 0;
  for (size_t i = 0; i < v.size(); ++i) order[i] = i, total += (*w)[i];
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return v[a] < v[b]; });
  const double pos = std::floor(std::clamp(q, 0.0, 1.0) * std::max(total - 1, 0.0));
  double cum = 0;
  for (size_t i : order) {
    cum += (*w)[i];
    if (cum > pos) return v[i];
  }
  return v[order.back()];
}

const char* kEdgeName[4] = {"+x", "+y", "-x", "-y"};

// Keeps the interval [c - h, c + h] inside [-limit, limit]; true when it had to be cut.
bool clamp_to_roi(double limit, double* c, double* h) {
  const double lo = std::max(*c - *h, -limit), hi = std::min(*c + *h, limit);
  const bool cut = lo > *c - *h || hi < *c + *h;
  if (cut && hi > lo) *c = 0.5 * (lo + hi), *h = 0.5 * (hi - lo);
  return cut;
}

core::Status check_config(const PlateRoi& roi, const PlateFitConfig& c) {
  if (!(roi.size_m.minCoeff() > 0) || !roi.size_m.allFinite())
    return core::InvalidArgument("plate ROI: size_m must be positive, got [" +
                                 std::to_string(roi.size_m.x()) + ", " + std::to_string(roi.size_m.y()) +
                                 ", " + std::to_string(roi.size_m.z()) + "]");
  if (!(roi.margin_in_plane_m >= 0) || !(roi.margin_normal_m >= 0))
    return core::InvalidArgument("plate ROI: margins must be >= 0");
  if (c.sampling == CloudSampling::kVoxelMeans && !(c.voxel_m > 0 && std::isfinite(c.voxel_m)))
    return core::InvalidArgument("plate fit: voxel-mean sampling needs voxel_m > 0, got " +
                                 std::to_string(c.voxel_m));
  if (c.has_viewpoint && !c.viewpoint_world.allFinite())
    return core::InvalidArgument("plate fit: viewpoint_world is not finite");
  if (!(c.plane_inlier_m > 0) || !(c.edge_band_m > 0) || !(c.edge_band_out_m > 0) ||
      !(c.corner_margin_m >= 0) || !(c.max_normal_angle_rad > 0 && c.max_normal_angle_rad < M_PI / 2) ||
      c.ransac_iterations < 1 || c.min_inliers < 3 || c.min_edge_samples < 1 || c.max_iterations < 1)
    return core::InvalidArgument(
        "plate fit: plane_inlier_m, edge_band_m, edge_band_out_m must be > 0, corner_margin_m >= 0, "
        "max_normal_angle_rad in (0, pi/2), ransac_iterations >= 1, min_inliers >= 3, min_edge_samples >= 1, "
        "max_iterations >= 1");
  return core::Status::Ok();
}

// Weighted least-squares plane (weighted centroid, smallest-eigenvalue direction of the weighted
// scatter) of the points within thr of (n, c); W[i] is the weight of P[i].
bool refine_plane(const std::vector<Eigen::Vector3d>& P, const std::vector<double>& W, double thr,
                  Eigen::Vector3d* n, Eigen::Vector3d* c) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double cnt = 0;
  for (size_t i = 0; i < P.size(); ++i)
    if (std::fabs(n->dot(P[i] - *c)) <= thr) sum += W[i] * P[i], cnt += W[i];
  if (cnt < 3) return false;
  const Eigen::Vector3d mean = sum / cnt;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < P.size(); ++i) {
    if (std::fabs(n->dot(P[i] - *c)) <= thr) {
      const Eigen::Vector3d d = P[i] - mean;
      const Eigen::Vector3d wd = W[i] * d;
      cov += wd * d.transpose();
    }
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  Eigen::Vector3d nn = es.eigenvectors().col(0);
  if (nn.dot(*n) < 0) nn = -nn;
  *n = nn;
  *c = mean;
  return true;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

core::Expected<WeldGroundTruth> parse_weld_groundtruth(const std::string& yaml_text,
                                                       const std::string& source_name) {
  auto doc = core::ConfigDocument::parse(yaml_text, source_name);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  WeldGroundTruth gt;
  std::string frame;
  root.require("frame", &frame).get("scenario", &gt.scenario);
  if (!frame.empty() && frame != "world")
    root.record_error("frame", "expected 'world' (the run's frame), got '" + frame + "'");
  if (!root.has("plates")) root.record_error("plates", "required but missing");
  std::vector<core::ConfigMap> plates = root.list("plates");
  std::vector<core::ConfigMap> seams = root.list("seams");
  for (core::ConfigMap& m : plates) {
    PlateTruth p;
    read_plate(m, &p);
    for (const PlateTruth& q : gt.plates)
      if (!p.name.empty() && q.name == p.name)
        m.record_error("name", "duplicate plate name '" + p.name + "'");
    gt.plates.push_back(std::move(p));
  }
  const std::vector<std::string> lines = split_lines(yaml_text);
  std::vector<std::string> plates_keys_read;  // "seams[i].plates" taken from the text
  for (size_t i = 0; i < seams.size(); ++i) {
    core::ConfigMap& m = seams[i];
    SeamTruth s;
    std::string type;
    m.require("name", &s.name).require("type", &type).require("start_world", &s.start_world);
    m.require("end_world", &s.end_world);
    if (type == "fillet") {
      s.type = SeamType::kFillet;
    } else if (type == "butt") {
      s.type = SeamType::kButt;
    } else if (!type.empty()) {
      m.record_error("type", "expected fillet or butt, got '" + type + "'");
    }
    if (!m.has("plates")) {
      m.record_error("plates", "required but missing");
    } else {
      const int last = i + 1 < seams.size() ? seams[i + 1].line() : static_cast<int>(lines.size()) + 1;
      std::string value, problem;
      std::vector<std::string> names;
      if (!find_plates_line(lines, m.line(), last, &value)) {
        m.record_error("plates", "expected a one-line list of plate names like [\"a\", \"b\"]");
      } else if (!parse_name_list(value, &names, &problem)) {
        m.record_error("plates", problem);
      } else if (names.size() != 2) {
        m.record_error("plates", "expected 2 plate names, got " + std::to_string(names.size()));
      } else {
        for (int k = 0; k < 2; ++k) {
          const std::string& nm = names[static_cast<size_t>(k)];
          const bool known = std::any_of(gt.plates.begin(), gt.plates.end(),
                                         [&](const PlateTruth& p) { return p.name == nm; });
          if (!known) m.record_error("plates", "'" + nm + "' is not a plate of this file");
          s.plates[static_cast<size_t>(k)] = nm;
        }
      }
      plates_keys_read.push_back("unknown key '" + m.path() + ".plates'");
    }
    gt.seams.push_back(std::move(s));
  }
  for (const std::string& e : doc->all_errors()) {
    const bool read_from_text =
        std::any_of(plates_keys_read.begin(), plates_keys_read.end(), [&](const std::string& k) {
          return e.size() >= k.size() && e.compare(e.size() - k.size(), k.size(), k) == 0;
        });
    if (!read_from_text) return core::ParseError(e);
  }
  return gt;
}

core::Expected<WeldGroundTruth> read_weld_groundtruth(const std::string& path) {
  std::string text;
  HWR_RETURN_IF_ERROR(core::read_file(path, &text));
  return parse_weld_groundtruth(text, path);
}

core::Expected<std::vector<CloudPoint>> read_cloud_file(const std::string& path) {
  std::string bytes;
  HWR_RETURN_IF_ERROR(core::read_file(path, &bytes));
  if (bytes.size() % kCloudRecordBytes != 0) {
    return core::CorruptData(
        path + ": " + std::to_string(bytes.size()) +
        " bytes is not a whole number of 16-byte point records (truncated or not a cloud file)");
  }
  std::vector<CloudPoint> out(bytes.size() / kCloudRecordBytes);
  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
  for (size_t i = 0; i < out.size(); ++i, b += kCloudRecordBytes) {
    CloudPoint& p = out[i];
    p.x_m = load_f32_le(b);
    p.y_m = load_f32_le(b + 4);
    p.z_m = load_f32_le(b + 8);
    p.r = b[12], p.g = b[13], p.b = b[14], p.flags = b[15];
    if (!std::isfinite(p.x_m) || !std::isfinite(p.y_m) || !std::isfinite(p.z_m))
      return core::CorruptData(path + ": point " + std::to_string(i) + " has a non-finite coordinate");
  }
  return out;
}

core::Status write_cloud_file(const std::string& path, const CloudPoint* points, size_t n) {
  std::vector<unsigned char> bytes(n * kCloudRecordBytes);
  unsigned char* b = bytes.data();
  for (size_t i = 0; i < n; ++i, b += kCloudRecordBytes) {
    store_f32_le(points[i].x_m, b);
    store_f32_le(points[i].y_m, b + 4);
    store_f32_le(points[i].z_m, b + 8);
    b[12] = points[i].r, b[13] = points[i].g, b[14] = points[i].b, b[15] = points[i].flags;
  }
  return core::write_file_atomic(path, bytes);
}

double OrientedBox::distance_m(const Eigen::Vector3d& p_world_m) const {
  const Eigen::Vector3d q = T_world_box.inverse(Eigen::Isometry) * p_world_m;
  return (q.cwiseAbs() - half_size_m).cwiseMax(0.0).norm();
}

PlateRoi plate_roi_from_truth(const WeldGroundTruth& gt, size_t i, double margin_in_plane_m,
                              double margin_normal_m) {
  PlateRoi roi;
  roi.T_world_plate = gt.plates[i].T_world_plate;
  roi.size_m = gt.plates[i].size_m;
  roi.margin_in_plane_m = margin_in_plane_m;
  roi.margin_normal_m = margin_normal_m;
  for (size_t j = 0; j < gt.plates.size(); ++j) {
    if (j == i) continue;
    OrientedBox b;
    b.T_world_box = gt.plates[j].T_world_plate;
    b.half_size_m = 0.5 * gt.plates[j].size_m;
    roi.others.push_back(b);
  }
  return roi;
}

// Edges on a support (header): the face's height again from its interior (the band-mean stage's plane
// takes in support points near the edges when the plate is thin against the noise), then every edge
// with a support beyond it placed by plate_detail::refine_edge_on_support.
static void refine_support_edges(const std::vector<Eigen::Vector3d>& P, const std::vector<double>& W,
                                 const PlateRoi& roi, const PlateFitConfig& config,
                                 const Eigen::Vector3d& nrm, const Eigen::Vector3d& e_u,
                                 const Eigen::Vector3d& e_w, Eigen::Vector3d* o_face, Vec2* centre,
                                 double* hu, double* hw, double phi, double corner_margin, PlateFit* fit) {
  using plate_detail::RaySample;
  const double T = roi.size_m.z();
  // Where the model starts: the band mean's rectangle, except along an axis where it reaches past
  // the ROI's own extent by more than a centimetre (the band mean merged the plate with its support
  // there): there the ROI's centre and size, which a detection gives to centimetres.
  const Eigen::Matrix2d R0 = Eigen::Rotation2Dd(phi).toRotationMatrix();
  const double nominal[2] = {0.5 * roi.size_m.x(), 0.5 * roi.size_m.y()};
  double* half[2] = {hu, hw};
  for (int a = 0; a < 2; ++a) {
    if (*half[a] <= nominal[a] + 0.01) continue;
    *half[a] = nominal[a];
    // The centre back onto the ROI's along this rectangle axis.
    const Vec2 axis = R0.col(a);
    *centre -= axis.dot(*centre) * axis;
  }
  const Eigen::Matrix2d R = R0;
  // Rectangle frame: x, y along the fitted rectangle's axes from its centre, z along the normal.
  auto rect = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d d = p - *o_face;
    const Vec2 r = R.transpose() * (Vec2(e_u.dot(d), e_w.dot(d)) - *centre);
    return Eigen::Vector3d(r.x(), r.y(), nrm.dot(d));
  };
  // The face's plane again, from its interior and the rays. The band-mean stage's plane takes in
  // support points near the edges, and under noise along oblique rays a fit of the observed points
  // tilts (a point's height error and its error in the face come from the same range error). Each
  // interior point is slid along its ray onto the current plane, where its place in the face is
  // exact, and the plane is fitted to the observed heights over those places (weighted least
  // squares, three rounds, points within half a thickness of the plane).
  const double inset = config.support_interior_inset_m;
  std::vector<Eigen::Vector3d> Q(P.size());
  for (size_t i = 0; i < P.size(); ++i) Q[i] = rect(P[i]);
  Eigen::Vector3d v = rect(config.viewpoint_world);
  if (!(v.z() > 0)) return;       // seen from behind the face: no model
  double pa = 0, pb = 0, pc = 0;  // the plane z = pa x + pb y + pc (rectangle frame)
  for (int round = 0; round < 3; ++round) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    int used = 0;
    for (size_t i = 0; i < Q.size(); ++i) {
      const Eigen::Vector3d& q = Q[i];
      if (!(std::fabs(q.x()) < *hu - inset && std::fabs(q.y()) < *hw - inset)) continue;
      if (std::fabs(q.z() - (pa * q.x() + pb * q.y() + pc)) > 0.5 * T) continue;
      const Eigen::Vector3d d = q - v;
      const double den = d.z() - pa * d.x() - pb * d.y();
      if (std::fabs(den) < 1e-9) continue;
      const double lambda = (pa * v.x() + pb * v.y() + pc - v.z()) / den;
      const Eigen::Vector3d x0(v.x() + lambda * d.x(), v.y() + lambda * d.y(), 1.0);
      A += W[i] * x0 * x0.transpose();
      rhs += W[i] * q.z() * x0;
      ++used;
    }
    if (used < 50) return;
    const Eigen::Vector3d abc = A.ldlt().solve(rhs);
    if (!abc.allFinite()) return;
    pa = abc.x(), pb = abc.y(), pc = abc.z();
  }
  // Into the refitted plane's frame: origin (0, 0, pc), normal (-pa, -pb, 1), x along (1, 0, pa).
  const Eigen::Vector3d n1 = Eigen::Vector3d(-pa, -pb, 1.0).normalized();
  const Eigen::Vector3d x1 = Eigen::Vector3d(1.0, 0.0, pa).normalized(), y1 = n1.cross(x1);
  const Eigen::Vector3d o1(0, 0, pc);
  auto refit = [&](const Eigen::Vector3d& q) {
    const Eigen::Vector3d d = q - o1;
    return Eigen::Vector3d(x1.dot(d), y1.dot(d), n1.dot(d));
  };
  for (Eigen::Vector3d& q : Q) q = refit(q);
  v = refit(v);
  *o_face += pc * nrm;
  const Eigen::Vector3d vp = v;
  // Range noise from the interior points.
  std::vector<RaySample> face;
  for (size_t i = 0; i < P.size(); ++i) {
    if (std::fabs(Q[i].x()) < *hu - inset && std::fabs(Q[i].y()) < *hw - inset &&
        std::fabs(Q[i].z()) < 0.5 * T)
      face.push_back({Q[i], vp, W[i]});
  }
  plate_detail::RangeNoise noise;
  if (!noise.fit(face)) return;
  double off[4] = {*hu, *hw, *hu, *hw};  // +x, +y, -x, -y outward offsets
  for (int k = 0; k < 4; ++k) {
    // Edge frame: s outward, t along the edge, h; the edge at s = off[k].
    const Vec2 n2 = kEdgeNormal[k], t2 = kEdgeTangent[k];
    const double half_t = (k % 2 == 0) ? *hw : *hu;
    auto to_edge = [&](const Eigen::Vector3d& q) {
      const Vec2 r(q.x(), q.y());
      return Eigen::Vector3d(n2.dot(r), t2.dot(r), q.z());
    };
    const Eigen::Vector3d vp_e = to_edge(vp);
    // What lies beyond: the weighted median height past the edge (outside a plate's shadow).
    std::vector<std::pair<double, double>> beyond;
    std::vector<RaySample> samples;
    for (size_t i = 0; i < Q.size(); ++i) {
      const Eigen::Vector3d q = to_edge(Q[i]);
      if (std::fabs(q.y()) > half_t - corner_margin) continue;
      if (q.x() > off[k] + config.support_probe_from_m && q.x() < off[k] + config.support_probe_to_m)
        beyond.emplace_back(q.z(), W[i]);
      if (q.x() > off[k] - config.support_band_in_m && q.x() < off[k] + config.support_probe_to_m &&
          q.z() > -2.5 * T - 0.01 && q.z() < 0.01 + 1.5 * T)
        samples.push_back({q, vp_e, W[i]});
    }
    double beyond_w = 0;
    for (const auto& [h, w] : beyond) beyond_w += w;
    if (beyond_w < config.support_min_weight) continue;
    std::sort(beyond.begin(), beyond.end());
    double a = 0, depth = 0;
    for (const auto& [h, w] : beyond) {
      a += w;
      if (a >= 0.5 * beyond_w) {
        depth = -h;
        break;
      }
    }
    if (!(depth > config.support_depth_min_ratio * T && depth < config.support_depth_max_ratio * T)) continue;
    const double D = config.support_depth_from_roi ? T : depth;
    const plate_detail::EdgeOnSupport e =
        plate_detail::refine_edge_on_support(samples, noise, off[k], D, config.support_search_m, 0.0002);
    if (!e.ok) continue;
    off[k] = e.edge_s;
    fit->edge_on_support[static_cast<size_t>(k)] = true;
    ++fit->edges_on_support;
  }
  // The rectangle from the four offsets (in the rectangle frame; back to face coordinates).
  const Vec2 shift = R * Vec2(0.5 * (off[0] - off[2]), 0.5 * (off[1] - off[3]));
  *centre += shift;
  *hu = 0.5 * (off[0] + off[2]);
  *hw = 0.5 * (off[1] + off[3]);
}

core::Expected<PlateFit> fit_plate(const CloudPoint* points, size_t n, const PlateRoi& roi,
                                   const PlateFitConfig& config, const float* weights) {
  HWR_RETURN_IF_ERROR(check_config(roi, config));
  if (points == nullptr && n > 0) return core::InvalidArgument("plate fit: null points with n > 0");
  // Weights (header, "Weights"): multiplicities of raw points. Without them every weight is 1.0,
  // which leaves every sum, count and comparison below bit-identical to the unweighted fit.
  bool integer_weights = true;
  if (weights != nullptr) {
    if (config.sampling != CloudSampling::kRawPoints)
      return core::InvalidArgument(
          "plate fit: weights are for kRawPoints (a voxel mean's count does not enter the centroid "
          "inversion)");
    for (size_t i = 0; i < n; ++i) {
      const float w = weights[i];
      if (!(std::isfinite(w) && w > 0)) {
        char buf[48];
        std::snprintf(buf, sizeof(buf), "%g", static_cast<double>(w));
        return core::InvalidArgument("plate fit: weight " + std::to_string(i) + " is " + buf +
                                     " (weights must be finite and > 0)");
      }
      integer_weights = integer_weights && w == std::floor(w);
    }
  }
  PlateFit fit;

  // ROI: the plate box inflated by the margins, other plates' points left out.
  const OrientedBox own{roi.T_world_plate, 0.5 * roi.size_m};
  const Eigen::Isometry3d T_plate_world = roi.T_world_plate.inverse(Eigen::Isometry);
  const Eigen::Vector3d half =
      0.5 * roi.size_m + Eigen::Vector3d(roi.margin_in_plane_m, roi.margin_in_plane_m, roi.margin_normal_m);
  std::vector<Eigen::Vector3d> P;
  std::vector<double> W;  // W[i]: weight of P[i]
  double roi_weight = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p(points[i].x_m, points[i].y_m, points[i].z_m);
    const Eigen::Vector3d q = T_plate_world * p;
    if (std::fabs(q.x()) > half.x() || std::fabs(q.y()) > half.y() || std::fabs(q.z()) > half.z()) continue;
    // A point nearer another plate's box than this plate's belongs to the other plate.
    const double d_own = own.distance_m(p);
    bool excluded = false;
    for (const OrientedBox& b : roi.others) excluded = excluded || b.distance_m(p) < d_own;
    if (excluded) continue;
    P.push_back(p);
    W.push_back(weights != nullptr ? static_cast<double>(weights[i]) : 1.0);
    roi_weight += W.back();
  }
  fit.roi_points = rounded_count(roi_weight);
  if (roi_weight < config.min_inliers) {
    fit.reason = std::to_string(fit.roi_points) + " points in the ROI (min " +
                 std::to_string(config.min_inliers) + ")";
    return fit;
  }

  // a. Plane: RANSAC with the normal prior, then least squares on the inliers.
  const Eigen::Vector3d x_roi = roi.T_world_plate.linear().col(0);
  const Eigen::Vector3d z_roi = roi.T_world_plate.linear().col(2);
  const Eigen::Vector3d o_roi = roi.T_world_plate.translation();
  const double cos_max = std::cos(config.max_normal_angle_rad);
  const double thr = config.plane_inlier_m;
  std::mt19937 rng(config.seed);
  // Minimal samples: uniform over the points without weights; with weights, over the weight-expanded
  // cloud (point i taken with probability W[i] / sum W). Integer weights below 2^53 draw the index
  // into the expanded cloud exactly as uniform sampling of the duplicated points does (same seed, same
  // draws, same points picked); other weights draw a real position in [0, sum W).
  std::vector<double> cum;  // cumulative weights
  if (weights != nullptr) {
    cum.resize(W.size());
    double acc = 0;
    for (size_t i = 0; i < W.size(); ++i) cum[i] = acc += W[i];
    integer_weights = integer_weights && acc < 9007199254740992.0;  // 2^53: sums exact
  }
  std::uniform_int_distribution<size_t> pick(
      0, weights != nullptr && integer_weights ? static_cast<size_t>(roi_weight) - 1 : P.size() - 1);
  std::uniform_real_distribution<double> pick_real(0.0, roi_weight);
  auto draw = [&]() -> size_t {
    if (weights == nullptr) return pick(rng);
    const double x = integer_weights ? static_cast<double>(pick(rng)) : pick_real(rng);
    const size_t i = static_cast<size_t>(std::upper_bound(cum.begin(), cum.end(), x) - cum.begin());
    return std::min(i, P.size() - 1);
  };
  double best = -1;  // the winner's inlier weight
  double best_cost = std::numeric_limits<double>::infinity();
  Eigen::Vector3d n_best = z_roi, c_best = o_roi;
  for (int it = 0; it < config.ransac_iterations; ++it) {
    const size_t a = draw(), b = draw(), c = draw();
    if (a == b || b == c || a == c) continue;
    Eigen::Vector3d nn = (P[b] - P[a]).cross(P[c] - P[a]);
    const double len = nn.norm();
    if (len < 1e-12) continue;
    nn /= len;
    if (std::fabs(nn.dot(z_roi)) < cos_max) continue;
    // MSAC score (Torr & Zisserman 2000): truncated squared distance, so that a plane between the
    // two faces of a thin plate, which holds both faces' points at the threshold, loses.
    // Weighted: a point of weight k costs and counts k times.
    double cnt = 0;
    double cost = 0;
    for (size_t i = 0; i < P.size(); ++i) {
      const double d = nn.dot(P[i] - P[a]);
      cost += W[i] * std::min(d * d, thr * thr);
      if (std::fabs(d) <= thr) cnt += W[i];
    }
    if (cost < best_cost) best_cost = cost, best = cnt, n_best = nn, c_best = P[a];
  }
  if (best < config.min_inliers) {
    fit.reason = "no plane within " + std::to_string(config.max_normal_angle_rad) +
                 " rad of the ROI normal has " + std::to_string(config.min_inliers) + " points (best " +
                 std::to_string(rounded_count(std::max(best, 0.0))) + ")";
    return fit;
  }
  Eigen::Vector3d nrm = n_best, ctr = c_best;
  for (int it = 0; it < 3; ++it)
    if (!refine_plane(P, W, thr, &nrm, &ctr)) break;
  // Outward normal: the plate's centre lies behind the face.
  if (nrm.dot(ctr - o_roi) < 0 || (std::fabs(nrm.dot(ctr - o_roi)) < 1e-9 && nrm.dot(z_roi) < 0)) nrm = -nrm;
  fit.face_sign = nrm.dot(z_roi) >= 0 ? 1 : -1;
  fit.normal_world = nrm;
  double sq = 0;
  double inl = 0;  // inlier weight
  for (size_t i = 0; i < P.size(); ++i) {
    const double h = nrm.dot(P[i] - ctr);
    if (std::fabs(h) <= thr) sq += (W[i] * h) * h, inl += W[i];
  }
  fit.inliers = rounded_count(inl);
  fit.plane_rms_m = inl > 0 ? std::sqrt(sq / inl) : 0;
  if (inl < config.min_inliers) {
    fit.reason =
        std::to_string(fit.inliers) + " plane inliers (min " + std::to_string(config.min_inliers) + ")";
    return fit;
  }

  // Face frame: origin the ROI centre projected on the plane, u along the ROI's x, w = n x u.
  Eigen::Vector3d o_face = o_roi - nrm.dot(o_roi - ctr) * nrm;
  const Eigen::Vector3d e_u = (x_roi - x_roi.dot(nrm) * nrm).normalized();
  const Eigen::Vector3d e_w = nrm.cross(e_u);

  // Edge-stage points (header, "Edges"). Raw points: the open side of the face only. Voxel means: the
  // face's voxels: near it, and the cell one voxel further out along the normal holding no point
  // that is off the face (a surface crossing the face, like the bench under a web, is not face).
  const double h_max = std::max(2.5 * fit.plane_rms_m, 0.001);
  const bool voxel = config.sampling == CloudSampling::kVoxelMeans;
  // A boundary voxel that also holds the plate's side face sits lower, by up to half the side's
  // height in the cell (wall_fraction); the bench or the other face, a thickness down, stays out
  // (by h_max at least: noisier maps keep fewer of those boundary voxels).
  const double T = roi.size_m.z();
  const double h_min = voxel ? std::max(-(0.5 * std::min(T, config.voxel_m) + h_max), -T + h_max) : 0.0;
  const Eigen::Isometry3d T_grid_world = config.T_world_grid.inverse(Eigen::Isometry);
  const double voxel_m = voxel ? config.voxel_m : 1.0;
  GridCells other_cells(config.T_world_grid, voxel_m), face_cells(config.T_world_grid, voxel_m);
  if (voxel) {
    for (const auto& p : P) {
      const double h = nrm.dot(p - o_face);
      if (h < h_min || h > h_max) other_cells.add(p);
    }
  }
  std::vector<FacePoint> F;
  std::vector<double> FW;  // FW[i]: weight of F[i]
  double face_weight = 0;
  std::vector<VoxelCell> vcells;
  std::vector<double> hs;
  for (size_t i = 0; i < P.size(); ++i) {
    const Eigen::Vector3d& p = P[i];
    const Eigen::Vector3d d = p - o_face;
    const double h = nrm.dot(d);
    if (h < h_min || h > h_max) continue;
    if (voxel && other_cells.occupied(p + voxel_m * nrm)) continue;
    FacePoint f;
    f.q = Vec2(e_u.dot(d), e_w.dot(d));
    if (config.has_viewpoint && !voxel) {
      // Where the point's viewing ray meets the fitted face (PlateFitConfig::viewpoint_world).
      const Eigen::Vector3d ray = (p - config.viewpoint_world).normalized();
      const double c = nrm.dot(ray);
      if (std::fabs(c) >= 0.2) {
        const Eigen::Vector3d on_face = d - (h / c) * ray;
        f.q = Vec2(e_u.dot(on_face), e_w.dot(on_face));
      }
    }
    f.p_world = p;
    if (voxel) {
      VoxelCell c;
      if (voxel_cell(p, T_grid_world, config.T_world_grid, voxel_m, o_face, e_u, e_w, nrm, &c)) {
        f.cell = static_cast<int>(vcells.size());
        vcells.push_back(c);
        hs.push_back(std::fabs(h));
      }
    }
    F.push_back(f);
    FW.push_back(W[i]);
    face_weight += W[i];
  }
  // Wall fractions of the voxels; the face noise is the robust spread of the voxel means' heights.
  std::vector<double> wall(vcells.size(), 0.0);
  if (voxel && !hs.empty()) {
    const double sigma = std::max(1.4826 * median_of(hs), 1e-4);
    for (size_t i = 0; i < vcells.size(); ++i) wall[i] = wall_fraction(vcells[i], sigma, roi.size_m.z());
  }
  // Where the face continues (the boundary test of voxel_edge_samples).
  for (const FacePoint& f : F) face_cells.add(f.p_world);
  if (face_weight < config.min_inliers) {
    fit.reason = std::to_string(rounded_count(face_weight)) +
                 (voxel ? " face voxels" : " points on the open side of the face") + " (min " +
                 std::to_string(config.min_inliers) + ")";
    return fit;
  }

  // b. Rectangle: quantile start, then band-mean updates, then (voxel means) centroid inversion.
  Vec2 centre;
  double hu, hw, phi = 0;
  {
    std::vector<double> u(F.size()), w(F.size());
    for (size_t i = 0; i < F.size(); ++i) u[i] = F[i].q.x(), w[i] = F[i].q.y();
    const std::vector<double>* qw = weights != nullptr ? &FW : nullptr;
    const double u0 = quantile(u, 0.01, qw), u1 = quantile(u, 0.99, qw), w0 = quantile(w, 0.01, qw),
                 w1 = quantile(w, 0.99, qw);
    centre = Vec2(0.5 * (u0 + u1), 0.5 * (w0 + w1));
    hu = 0.5 * (u1 - u0) / 0.98;
    hw = 0.5 * (w1 - w0) / 0.98;
  }
  const double corner_margin =
      voxel ? std::max(config.corner_margin_m, 2 * config.voxel_m) : config.corner_margin_m;
  std::vector<Vec2> r(F.size());
  std::vector<EdgeSample> samples;
  const int count_iterations = config.max_iterations;
  std::array<bool, 4> fallback{};
  std::array<bool, 2> at_limit{};
  const double u_limit = 0.5 * roi.size_m.x() + roi.margin_in_plane_m;
  const double w_limit = 0.5 * roi.size_m.y() + roi.margin_in_plane_m;
  const int total_iterations = config.max_iterations * (voxel ? 2 : 1);
  int it = 0;
  for (; it < total_iterations; ++it) {
    const bool inversion = voxel && it >= count_iterations;
    const Eigen::Matrix2d R = Eigen::Rotation2Dd(phi).toRotationMatrix();
    for (size_t i = 0; i < F.size(); ++i) r[i] = R.transpose() * (F[i].q - centre);
    double off[4], slope_sum = 0, slope_w = 0;
    for (int k = 0; k < 4; ++k) {
      const double e = (k % 2 == 0) ? hu : hw;
      const double half_t = (k % 2 == 0) ? hw : hu;
      EdgeLine line;
      if (inversion) {
        voxel_edge_samples(r, F, vcells, wall, face_cells, centre, R, e_u, e_w, nrm, voxel_m, k, e, half_t,
                           corner_margin, &samples);
        line = fit_edge_line(samples, config.min_edge_samples);
      } else {
        // A deep band first, while the quantile start may be centimetres out; if it is inside instead,
        // each update moves the edge out by up to B_out.
        const bool start = it < 3;
        // Voxel means: at least 3 voxels behind the edge, and one past it.
        const double band = voxel ? std::max(config.edge_band_m, 3 * config.voxel_m) : config.edge_band_m;
        const double B = std::min(start ? 3 * band : band, 0.5 * e);
        double B_out = std::max(config.edge_band_out_m, 3 * fit.plane_rms_m);
        if (voxel) B_out = std::max(B_out, config.voxel_m);
        line = band_mean_edge(r, FW, k, e, B, B_out, half_t, corner_margin, config.min_edge_samples, !voxel);
        // The band fell off the points (the edge was pulled out past a gap): restart it from the
        // outermost point along the edge.
        if (!line.ok) line = outermost_edge(r, FW, k, half_t, corner_margin, config.min_edge_samples);
      }
      fit.edge_samples[static_cast<size_t>(k)] = line.used;
      if (inversion) fallback[static_cast<size_t>(k)] = !line.ok;
      if (inversion && !line.ok) {
        // Too few boundary voxels (a side face or a neighbour fills the cells past the edge): the
        // edge keeps its band-mean place.
        line.ok = true;
        line.offset = e;
        line.slope = 0;
        line.used = 0;
        line.weight = 0;
      }
      if (!line.ok) {
        fit.reason = std::string("edge ") + kEdgeName[k] + ": " + std::to_string(line.used) + " " +
                     (inversion ? "boundary voxels" : "points in the edge band") + " (min " +
                     std::to_string(config.min_edge_samples) + "): the plate is not observed along it";
        return fit;
      }
      off[k] = line.offset;
      slope_sum += line.weight * line.slope;
      slope_w += line.weight;
    }
    const double new_hu = 0.5 * (off[0] + off[2]), new_hw = 0.5 * (off[1] + off[3]);
    if (!(new_hu > 0) || !(new_hw > 0)) {
      fit.reason = "the fitted rectangle collapsed";
      return fit;
    }
    const Vec2 shift = R * Vec2(0.5 * (off[0] - off[2]), 0.5 * (off[1] - off[3]));
    const double dphi = std::clamp(slope_w > 0 ? -slope_sum / slope_w : 0.0, -0.05, 0.05);
    const double change = std::max({std::fabs(new_hu - hu), std::fabs(new_hw - hw), shift.norm()});
    // Half steps after the first updates of a stage: the band limits and the voxel selection move
    // with the estimate, which can otherwise settle into a two-step cycle around the fixed point.
    const int stage_it = inversion ? it - count_iterations : it;
    const double gain = stage_it < 4 ? 1.0 : 0.5;
    centre += gain * shift;
    hu += gain * (new_hu - hu), hw += gain * (new_hw - hw), phi += gain * dphi;
    // Edges stay inside the ROI: past it there are no points to place them by.
    const bool at_u = clamp_to_roi(u_limit, &centre.x(), &hu), at_w = clamp_to_roi(w_limit, &centre.y(), &hw);
    at_limit = {at_u, at_w};
    if (change < 1e-5 && std::fabs(dphi) < 1e-5) {
      if (!voxel || inversion) break;
      it = count_iterations - 1;  // band mean converged: go on with the inversion
    }
  }
  fit.iterations = it + 1;
  fit.edges_from_band_mean = static_cast<int>(std::count(fallback.begin(), fallback.end(), true));
  fit.at_roi_limit = at_limit[0] || at_limit[1];

  // Edges on a support, from the rays (header, "Edges on a support"; plate_edge_rays.hpp).
  if (config.has_viewpoint && !voxel && config.support_edges) {
    refine_support_edges(P, W, roi, config, nrm, e_u, e_w, &o_face, &centre, &hu, &hw, phi, corner_margin,
                         &fit);
    fit.at_roi_limit =
        std::fabs(centre.x()) + hu >= u_limit - 1e-9 || std::fabs(centre.y()) + hw >= w_limit - 1e-9;
  }

  // c. Results.
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(phi).toRotationMatrix();
  const Vec2 corner2[4] = {Vec2(-hu, -hw), Vec2(hu, -hw), Vec2(hu, hw), Vec2(-hu, hw)};
  for (int k = 0; k < 4; ++k) {
    const Vec2 q = centre + R * corner2[k];
    fit.corners_world[static_cast<size_t>(k)] = o_face + q.x() * e_u + q.y() * e_w;
  }
  fit.face_centre_world = o_face + centre.x() * e_u + centre.y() * e_w;
  fit.length_m = 2 * hu;
  fit.width_m = 2 * hw;
  fit.seen = true;
  return fit;
}

core::Expected<AeReport> compute_ae(const std::vector<PlateFit>& fits, const WeldGroundTruth& gt) {
  if (fits.size() != gt.plates.size())
    return core::InvalidArgument("compute_ae: " + std::to_string(fits.size()) + " fits for " +
                                 std::to_string(gt.plates.size()) + " ground-truth plates");
  AeReport rep;
  rep.plates_total = static_cast<int>(gt.plates.size());
  double dim_sum = 0, corner_sum = 0;
  for (size_t i = 0; i < fits.size(); ++i) {
    const PlateFit& f = fits[i];
    const PlateTruth& t = gt.plates[i];
    PlateAe a;
    a.name = t.name;
    a.seen = f.seen;
    a.reason = f.reason;
    a.gt_length_m = t.size_m.x();
    a.gt_width_m = t.size_m.y();
    if (f.seen) {
      a.length_m = f.length_m;
      a.width_m = f.width_m;
      a.length_error_mm = 1e3 * std::fabs(f.length_m - t.size_m.x());
      a.width_error_mm = 1e3 * std::fabs(f.width_m - t.size_m.y());
      double sum = 0;
      for (size_t k = 0; k < 4; ++k) {
        double best = std::numeric_limits<double>::infinity();
        for (size_t c = 0; c < 8; ++c) {
          const bool plus_z = (c & 1) != 0;
          if (plus_z != (f.face_sign > 0)) continue;
          best = std::min(best, (f.corners_world[k] - t.corners_world[c]).norm());
        }
        a.corner_error_mm[k] = 1e3 * best;
        sum += a.corner_error_mm[k];
      }
      a.mean_corner_error_mm = sum / 4;
      ++rep.plates_seen;
      dim_sum += a.length_error_mm + a.width_error_mm;
      corner_sum += sum;
    } else {
      a.length_m = a.width_m = kNaN;
      a.length_error_mm = a.width_error_mm = a.mean_corner_error_mm = kNaN;
      a.corner_error_mm.fill(kNaN);
    }
    rep.plates.push_back(std::move(a));
  }
  rep.ae_mm = rep.plates_seen > 0 ? dim_sum / (2.0 * rep.plates_seen) : kNaN;
  rep.ae_corner_mm = rep.plates_seen > 0 ? corner_sum / (4.0 * rep.plates_seen) : kNaN;
  return rep;
}

}  // namespace hwr::recon
