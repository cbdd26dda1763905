// BayesTreeSmoother: marginal covariances from the Bayes tree.
//
// The root's joint covariance is (R^T R)^-1. Walking down towards the
// variable's clique, each conditional x_F = R^-1 (d - S x_S) turns the joint
// covariance of its separator into that of frontals and separator:
//   Sigma_FF = R^-1 R^-T + K Sigma_SS K^T,  Sigma_FS = -K Sigma_SS,  K = R^-1 S.
// The newest pose sits in the root, so its covariance costs one small
// triangular inverse.
#include <Eigen/Dense>
#include <unordered_map>

#include "estimation/smoother/bayes_tree_smoother.h"

namespace rilo {

std::optional<CovarianceBlock> BayesTreeSmoother::marginalCovariance(Key key, std::string* failure) {
  auto fail = [&](const std::string& why) -> std::optional<CovarianceBlock> {
    if (failure) *failure = why;
    return std::nullopt;
  };
  auto it = key_to_var_.find(key);
  if (it == key_to_var_.end()) return fail("unknown variable " + keyString(key));
  const VarId var = it->second;
  if (vars_[var].clique == kNone) return fail("variable " + keyString(key) + " is not in the tree");

  std::vector<CliqueId> path;
  for (CliqueId c = vars_[var].clique; c != kNone; c = cliques_[c].parent) path.push_back(c);

  Eigen::MatrixXd joint;                     // over the previous clique's frontals + separator
  std::unordered_map<VarId, int> offset_of;  // variable -> offset in `joint`
  for (auto step = path.rbegin(); step != path.rend(); ++step) {
    const Clique& q = cliques_[*step];
    const int fd = q.frontal_dim;
    const int sd = q.separator_dim;
    Eigen::MatrixXd sigma_ss(sd, sd);
    std::vector<int> sep_offsets;
    for (VarId s : q.separator) sep_offsets.push_back(offset_of.at(s));
    for (std::size_t a = 0, ra = 0; a < q.separator.size(); ra += vars_[q.separator[a]].dim, ++a) {
      for (std::size_t b = 0, rb = 0; b < q.separator.size(); rb += vars_[q.separator[b]].dim, ++b) {
        sigma_ss.block(ra, rb, vars_[q.separator[a]].dim, vars_[q.separator[b]].dim) =
            joint.block(sep_offsets[a], sep_offsets[b], vars_[q.separator[a]].dim, vars_[q.separator[b]].dim);
      }
    }
    const Eigen::MatrixXd R_inv =
        q.conditional.topLeftCorner(fd, fd).triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(fd, fd));
    Eigen::MatrixXd next(fd + sd, fd + sd);
    next.topLeftCorner(fd, fd) = R_inv * R_inv.transpose();
    if (sd > 0) {
      const Eigen::MatrixXd K = R_inv * q.conditional.block(0, fd, fd, sd);
      const Eigen::MatrixXd K_sigma = K * sigma_ss;
      next.topLeftCorner(fd, fd) += K_sigma * K.transpose();
      next.topRightCorner(fd, sd) = -K_sigma;
      next.bottomLeftCorner(sd, fd) = -K_sigma.transpose();
      next.bottomRightCorner(sd, sd) = sigma_ss;
    }
    joint = std::move(next);
    offset_of.clear();
    int offset = 0;
    for (const auto* list : {&q.frontals, &q.separator}) {
      for (VarId v : *list) {
        offset_of[v] = offset;
        offset += vars_[v].dim;
      }
    }
  }
  const int dim = vars_[var].dim;
  CovarianceBlock out = joint.block(offset_of.at(var), offset_of.at(var), dim, dim);
  if (!out.allFinite()) return fail("covariance of " + keyString(key) + " is not finite (rank-deficient clique)");
  return out;
}

}  // namespace rilo
