#include "bonded/engine.h"
#include <cstdio>
int main() { hs::bonded::EngineDef d; hs::bonded::Engine e(d); std::printf("%zu\n", e.particles().size()); }
