// iSAM2's step policy: the Gauss-Newton step the Bayes tree solves, taken as
// it is (Kaess et al. 2012). D-iSAM2 falls back to it when an update has
// nothing to damp.
#include "estimation/smoother/bayes_tree_smoother.h"

namespace rilo {

void BayesTreeSmoother::stepGaussNewton(UpdateStats& stats) {
  clearUndo();
  backSubstitute(params_.wildfire_threshold, stats);
  refreshErrorsOfChanged(false);
  stats.step_tries = 1;
}

}  // namespace rilo
