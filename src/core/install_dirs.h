#pragma once
// Where an installed egopd keeps its data files: PREFIX/share/egopd/<sub>, PREFIX found from the running program
// (PREFIX/bin/egopd) and from the file holding egopd's code (PREFIX/lib/libegopd.so or PREFIX/lib/<multiarch>/...,
// for programs that load the library). The caller adds the source tree as its last candidate.
#include <filesystem>
#include <string>
#include <vector>

namespace egopd {

std::vector<std::filesystem::path> installed_data_candidates(const std::string& sub);

}  // namespace egopd
