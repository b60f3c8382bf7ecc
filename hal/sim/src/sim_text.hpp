#pragma once
// Private to hwr_sim: text helpers for the YAML and CSV files the simulator writes.

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/file_io.hpp"
#include "hwr/core/status.hpp"

namespace hwr::sim::text {

// Shortest decimal text that reads back to the same double (YAML spellings for nan/inf).
std::string num(double v);
std::string quoted(const std::string& s);
// "[a, b, c]"
std::string list(const double* v, int n);
inline std::string list(const Eigen::Vector2d& v) { return list(v.data(), 2); }
inline std::string list(const Eigen::Vector3d& v) { return list(v.data(), 3); }
// 4x4 row-major, 16 numbers.
std::string matrix16(const Eigen::Isometry3d& T);
// From 16 row-major numbers; false unless the last row is 0 0 0 1 and the rotation is orthonormal
// (|R^T R - I| < 1e-6, det > 0). The rotation is re-orthonormalised.
bool isometry_from16(const std::vector<double>& v, Eigen::Isometry3d* T);

// Whole-file read and write-to-temporary-then-rename (core/file_io.hpp).
using core::read_file;
using core::write_file_atomic;

}  // namespace hwr::sim::text
