// gridrt explain / stats / diff: the grid's own verbs (registered once the grid backends exist).
#include "apps/commands.h"

namespace gridrt::app {

void add_grid_commands(CLI::App&) {}

}  // namespace gridrt::app
