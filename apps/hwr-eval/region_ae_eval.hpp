#pragma once
// hwr-eval ae --map (region_ae_eval.cpp): argv as given to hwr-eval, argv[1] == "ae".
namespace hwr_eval {
int run_region_ae(int argc, char** argv);
}  // namespace hwr_eval
