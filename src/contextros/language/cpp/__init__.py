"""The C++ flavour of the layer language: the paper's Listing 1 form.

A header part of plain C++, then `Layer Name [ ... ]` blocks of C++ function definitions.
C++ is read with tree-sitter's C++ grammar (parser.py and its parts); the back end
(generator.py) writes a source and a header following the paper's Listing 2, dispatching
through the C++ runtime in cpp/core. The checker is shared with the Python flavour: both
build the same tree.
"""
