#pragma once
// hwr-eval map-update (map_update_eval.cpp): argv as given to hwr-eval, argv[1] == "map-update".
namespace hwr_eval {
int run_map_update(int argc, char** argv);
}  // namespace hwr_eval
