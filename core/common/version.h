#pragma once

namespace ism {

// `git describe` of the source tree this binary was built from (stamped into trained models'
// provenance and reported by the server).
const char* codeVersion();

}  // namespace ism
