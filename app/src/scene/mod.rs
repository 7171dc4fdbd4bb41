//! Scene inputs: models, environments (cube maps), backgrounds and the scene file.
