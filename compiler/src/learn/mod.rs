//! Template SPN structure generation, EM training and the model file.
