// gridrt convert: any scene the tool reads -> the binary cache (.gridscene), textures decoded.
// The cache loads without OpenImageIO: it is how real scenes travel to the GPU machine.
#include <cctype>
#include <cstdio>

#include "apps/commands.h"
#include "gridrt/common/scene_io.h"

namespace gridrt::app {

void add_convert_command(CLI::App& app) {
  auto scene = std::make_shared<std::string>();
  auto output = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand("convert", "Write a scene as a binary cache (.gridscene) that loads without OpenImageIO");
  cmd->add_option("scene", *scene, "A scene file (.json), a mesh, or builtin:NAME")->required();
  cmd->add_option("-o,--output", *output, "The .gridscene file to write")->required();
  cmd->callback([scene, output] {
    check_output_path(*output);
    std::string lower = *output;
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    // The command line's error, as every -o name a verb cannot write (exit 2)
    if (!lower.ends_with(".gridscene")) throw OptionsError("convert writes .gridscene files, not '" + *output + "'");
    const Scene s = load_scene_or_default(*scene);
    save_scene_binary(s, *output);
    std::fprintf(stderr, "wrote %s: %llu triangles, %zu instances, %zu textures\n", output->c_str(),
                 (unsigned long long)s.triangle_count(), s.instances.size(), s.textures.size());
  });
}

}  // namespace gridrt::app
