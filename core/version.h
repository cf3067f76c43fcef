/* version: marie's version, printed by every program's --version (and in marie.pc). */
#ifndef MARIE_VERSION_H
#define MARIE_VERSION_H
#define MARIE_VERSION "0.1.0"
#endif
