"""What is being imaged: triangle meshes with parts, materials and procedural satellites."""
