// FCLib files: the three storages of W read back exactly, clear errors on bad files, and the four
// shared problems (shared/fclib) solved to the FCLib error, checked independently with a dense
// u = W r + q and the natural map written out here.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <unistd.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "nlgs_solver/fclib_file.hpp"

#ifndef RUBBLE_FCLIB_DIR
#define RUBBLE_FCLIB_DIR ""
#endif

namespace rubble {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  return fs::temp_directory_path() / ("rubble_test_fclib_" + std::to_string(::getpid()) + "_" + name);
}

Eigen::MatrixXd dense(const SparseMatrix& W) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(W.rows, W.columns);
  for (int row = 0; row < W.rows; ++row)
    for (int e = W.row_start[static_cast<std::size_t>(row)]; e < W.row_start[static_cast<std::size_t>(row) + 1]; ++e)
      d(row, W.column[static_cast<std::size_t>(e)]) += W.value[static_cast<std::size_t>(e)];
  return d;
}

// A sparse problem with a few zero blocks (so the storages differ from a dense layout).
LocalProblem sparse_problem(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  LocalProblem p;
  const int m = static_cast<int>(3 * n);
  p.W.rows = p.W.columns = m;
  p.W.row_start.push_back(0);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) {
      if ((i / 3 + j / 3) % 3 == 1) continue;  // leave some blocks empty
      p.W.column.push_back(j);
      p.W.value.push_back(u(rng));
    }
    p.W.row_start.push_back(static_cast<int>(p.W.value.size()));
  }
  for (int i = 0; i < m; ++i) p.q.push_back(u(rng));
  for (std::size_t k = 0; k < n; ++k) p.mu.push_back(0.5 * (1.0 + u(rng)));
  return p;
}

TEST(FclibFile, TheThreeStoragesOfWReadBackExactly) {
  const LocalProblem p = sparse_problem(5, 3);
  for (const SparseStorage storage :
       {SparseStorage::compressed_row, SparseStorage::compressed_column, SparseStorage::triplet}) {
    const fs::path file = scratch("storage.hdf5");
    write_fclib_local(file, p, storage, "round trip");
    FclibFileInfo info;
    const LocalProblem back = read_fclib_local(file, &info);
    fs::remove(file);
    EXPECT_EQ(info.storage, storage);
    EXPECT_EQ(info.title, "round trip");
    EXPECT_EQ(back.q, p.q);
    EXPECT_EQ(back.mu, p.mu);
    EXPECT_EQ(back.W.row_start, p.W.row_start);
    EXPECT_EQ(back.W.column, p.W.column);
    EXPECT_EQ(back.W.value, p.W.value);
  }
}

// A hand-written triplet file, as another program would write it: entries out of order and a
// duplicate, which FCLib (CSparse) semantics sum.
TEST(FclibFile, TripletEntriesAreSortedAndDuplicatesSummed) {
  const fs::path file = scratch("triplet.hdf5");
  {
    LocalProblem p;
    p.W.rows = p.W.columns = 3;
    p.W.row_start = {0, 1, 2, 3};
    p.W.column = {0, 1, 2};
    p.W.value = {1.0, 2.0, 3.0};
    p.q = {-1.0, 0.0, 0.0};
    p.mu = {0.3};
    write_fclib_local(file, p, SparseStorage::triplet);
    // Overwrite i, p, x and nz with unordered entries (row, column): (2,2) 3, (0,0) 1, (1,1) 2,
    // (0,0) 0.5, (0,2) 4.
    const hid_t f = H5Fopen(file.string().c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    for (const char* name : {"/fclib_local/W/i", "/fclib_local/W/p", "/fclib_local/W/x", "/fclib_local/W/nz"})
      H5Ldelete(f, name, H5P_DEFAULT);
    const std::vector<int> rows{2, 0, 1, 0, 0}, columns{2, 0, 1, 0, 2};
    const std::vector<double> values{3.0, 1.0, 2.0, 0.5, 4.0};
    const int nz = 5;
    auto write = [&](const char* name, hid_t type, const void* data, hsize_t count) {
      const hid_t space = H5Screate_simple(1, &count, nullptr);
      const hid_t d = H5Dcreate2(f, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      H5Dwrite(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
      H5Dclose(d);
      H5Sclose(space);
    };
    write("/fclib_local/W/i", H5T_NATIVE_INT, rows.data(), 5);
    write("/fclib_local/W/p", H5T_NATIVE_INT, columns.data(), 5);
    write("/fclib_local/W/x", H5T_NATIVE_DOUBLE, values.data(), 5);
    write("/fclib_local/W/nz", H5T_NATIVE_INT, &nz, 1);
    H5Fclose(f);
  }
  const LocalProblem back = read_fclib_local(file);
  fs::remove(file);
  Eigen::Matrix3d expected;
  expected << 1.5, 0, 4, 0, 2, 0, 0, 0, 3;
  EXPECT_EQ(dense(back.W), Eigen::MatrixXd(expected));
}

/// Whether reading `file` throws an FclibFileError whose message names the file and holds
/// `fragment` (for EXPECT_TRUE).
::testing::AssertionResult rejected_with(const fs::path& file, const std::string& fragment) {
  try {
    read_fclib_local(file);
  } catch (const FclibFileError& e) {
    const std::string message = e.what();
    if (message.find(file.string()) != std::string::npos && message.find(fragment) != std::string::npos) {
      return ::testing::AssertionSuccess();
    }
    return ::testing::AssertionFailure() << "message \"" << message << "\" lacks the file name or \"" << fragment
                                         << "\"";
  }
  return ::testing::AssertionFailure() << "no error for " << file;
}

// The command line maps every InputError to exit code 2 by the base (docs/exit-codes.md).
TEST(FclibFile, AnUnreadableFileIsAnInputErrorNamingTheFile) {
  const fs::path missing = scratch("missing.hdf5");
  try {
    read_fclib_local(missing);
    ADD_FAILURE() << "no error for " << missing;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string()), std::string::npos) << e.what();
  }
}

TEST(FclibFile, BadFilesGiveMessagesNamingFileAndDataset) {
  EXPECT_TRUE(rejected_with(scratch("missing.hdf5"), "no such file"));

  const fs::path text = scratch("text.hdf5");
  {
    std::FILE* f = std::fopen(text.string().c_str(), "w");
    std::fputs("not hdf5", f);
    std::fclose(f);
  }
  EXPECT_TRUE(rejected_with(text, "not an HDF5 file"));
  fs::remove(text);

  const fs::path solution = scratch("solution.hdf5");
  write_fclib_solution(solution, {1, 2, 3}, {4, 5, 6});
  EXPECT_TRUE(rejected_with(solution, "/fclib_local"));
  std::vector<double> r, u;
  read_fclib_solution(solution, r, u);
  EXPECT_EQ(r, (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(u, (std::vector<double>{4, 5, 6}));
  fs::remove(solution);

  LocalProblem p = sparse_problem(2, 1);
  p.q.pop_back();
  const fs::path short_q = scratch("short_q.hdf5");
  write_fclib_local(short_q, p);
  EXPECT_TRUE(rejected_with(short_q, "/fclib_local/vectors/q"));
  fs::remove(short_q);

  p = sparse_problem(2, 1);
  p.W.column[3] = 17;  // outside the 6 columns
  const fs::path bad_index = scratch("bad_index.hdf5");
  write_fclib_local(bad_index, p);
  EXPECT_TRUE(rejected_with(bad_index, "/fclib_local/W/i"));
  fs::remove(bad_index);

  p = sparse_problem(2, 1);
  p.mu[1] = -0.1;
  const fs::path negative_mu = scratch("negative_mu.hdf5");
  write_fclib_local(negative_mu, p);
  EXPECT_TRUE(rejected_with(negative_mu, "/fclib_local/vectors/mu"));
  fs::remove(negative_mu);
}

// ---- the shared problems

// Contacts as listed in the FCLib problem set's README; trace(W), sum_ij W_ij (i mod 7)(j mod 5) and |q| from an
// independent read with h5py + scipy.sparse.csr_matrix; symmetric: W = W^T to round-off (the
// Capsules operator is not: its asymmetry is 1.3e-3 of max|W| in the file itself).
struct SharedProblem {
  const char* file;
  std::size_t contacts;
  double trace, weighted_sum, q_norm;
  bool symmetric;
};
const SharedProblem shared_problems[] = {
    {"Capsules-i125-1213.hdf5", 286, 2244.864825459496, 19736.18115630696, 7.083790136323755, false},
    {"fclib_local_problem_test_BoxesStack.hdf5", 48, 77409.55728645294, 1173492.3871222162, 0.009810000175844958, true},
    {"Box_Stacks-i0122-82-5_local.hdf5", 82, 767.4163364896939, 9179.083985283316, 0.011247583260269391, true},
    {"Spheres-i099-356-679_local.hdf5", 356, 4801.869814234509, 30105.125117931737, 24.78331306859791, true},
};

fs::path shared_file(const char* name) { return fs::path(RUBBLE_FCLIB_DIR) / name; }

// The FCLib error written out independently of the library: dense u = W r + q, then per contact
// F = r - P_K(r - u_hat) with the cone projection in closed form.
double independent_error(const LocalProblem& p, const std::vector<double>& r) {
  const auto m = static_cast<Eigen::Index>(p.q.size());
  const Eigen::VectorXd rv = Eigen::Map<const Eigen::VectorXd>(r.data(), m);
  const Eigen::VectorXd u = dense(p.W) * rv + Eigen::Map<const Eigen::VectorXd>(p.q.data(), m);
  double f2 = 0.0;
  for (Eigen::Index k = 0; k < m / 3; ++k) {
    const double mu = p.mu[static_cast<std::size_t>(k)];
    const Eigen::Vector3d rk = rv.segment<3>(3 * k);
    Eigen::Vector3d x = rk - u.segment<3>(3 * k);
    x(0) -= mu * u.segment<2>(3 * k + 1).norm();
    const double xn = x(0), xt = x.tail<2>().norm();
    Eigen::Vector3d projection;
    if (xt <= mu * xn)
      projection = x;
    else if (mu * xt <= -xn)
      projection.setZero();
    else {
      const double pn = (xn + mu * xt) / (1 + mu * mu);
      projection << pn, mu * pn * x(1) / xt, mu * pn * x(2) / xt;
    }
    f2 += (rk - projection).squaredNorm();
  }
  return std::sqrt(f2) / Eigen::Map<const Eigen::VectorXd>(p.q.data(), m).norm();
}

class SharedFclib : public ::testing::TestWithParam<SharedProblem> {
 protected:
  void SetUp() override {
    // Missing data is a failure, not a skip: a gate that passes without solving these problems
    // would claim what it did not check.
    ASSERT_TRUE(fs::exists(shared_file(GetParam().file)))
        << "FCLib test data not found at " << shared_file(GetParam().file)
        << " (the repository's sibling folder shared/fclib; see tests/nlgs_solver/CMakeLists.txt)";
  }
};

TEST_P(SharedFclib, ReadsTheDelassusOperatorAsAnIndependentReaderDoes) {
  const SharedProblem& expected = GetParam();
  FclibFileInfo info;
  const LocalProblem p = read_fclib_local(shared_file(expected.file), &info);
  EXPECT_EQ(p.contact_count(), expected.contacts);
  EXPECT_EQ(info.storage, SparseStorage::compressed_row);
  const Eigen::MatrixXd W = dense(p.W);
  EXPECT_NEAR(W.trace(), expected.trace, 1e-12 * expected.trace);
  double weighted = 0.0;
  for (Eigen::Index i = 0; i < W.rows(); ++i)
    for (Eigen::Index j = 0; j < W.cols(); ++j) weighted += W(i, j) * static_cast<double>((i % 7) * (j % 5));
  EXPECT_NEAR(weighted, expected.weighted_sum, 1e-10 * std::abs(expected.weighted_sum));
  EXPECT_NEAR(Eigen::Map<const Eigen::VectorXd>(p.q.data(), static_cast<Eigen::Index>(p.q.size())).norm(),
              expected.q_norm, 1e-12 * expected.q_norm);
  const double asymmetry = (W - W.transpose()).cwiseAbs().maxCoeff() / W.cwiseAbs().maxCoeff();
  if (expected.symmetric) {
    EXPECT_LE(asymmetry, 1e-12);
  }
  // Delassus operators are positive semi-definite (their symmetric part is).
  const Eigen::MatrixXd symmetric_part = 0.5 * (W + W.transpose());
  EXPECT_GE(
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(symmetric_part, Eigen::EigenvaluesOnly).eigenvalues().minCoeff(),
      -1e-10 * W.cwiseAbs().maxCoeff());
}

// rubble fclib's default (sweeps + polish) on all four; the plain sweeps too, except on BoxesStack
// where they need 34 350 sweeps (0.7 s in Release, minutes under the sanitizers; the figure is in
// bench/RESULTS.md, "Solver (FCLib)").
TEST_P(SharedFclib, ReachesTenToTheMinusFour) {
  const LocalProblem p = read_fclib_local(shared_file(GetParam().file));
  LocalProblemOptions options;
  options.tolerance = 1e-4;
  options.max_iterations = 2000;
  options.polish = PolishMethod::newton;
  const LocalProblemSolution polished = solve_local_problem(p, options);
  EXPECT_TRUE(polished.converged) << polished.error;
  EXPECT_LE(independent_error(p, polished.r), 1e-4);
  if (std::string(GetParam().file).find("BoxesStack") != std::string::npos) return;
  options.polish = PolishMethod::none;
  const LocalProblemSolution plain = solve_local_problem(p, options);
  EXPECT_TRUE(plain.converged) << plain.error;
  EXPECT_EQ(plain.newton_iterations, 0);
  EXPECT_LE(independent_error(p, plain.r), 1e-4);
}

TEST_P(SharedFclib, NewtonPolishReachesTenToTheMinusEight) {
  const LocalProblem p = read_fclib_local(shared_file(GetParam().file));
  for (const SweepOrder order : {SweepOrder::as_stored, SweepOrder::shuffled}) {
    LocalProblemOptions options;
    options.tolerance = 1e-8;
    options.max_iterations = 2000;
    options.polish = PolishMethod::newton;
    options.order = order;
    const LocalProblemSolution s = solve_local_problem(p, options);
    EXPECT_TRUE(s.converged) << s.error;
    EXPECT_LE(independent_error(p, s.r), 1e-8);
    // u returned with r is W r + q.
    EXPECT_NEAR(fclib_error(p, s.r, s.u), s.error, 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(Shared, SharedFclib, ::testing::ValuesIn(shared_problems), [](const auto& info) {
  std::string name = info.param.file;
  name = name.substr(0, name.find('.'));
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
});

}  // namespace
}  // namespace rubble
