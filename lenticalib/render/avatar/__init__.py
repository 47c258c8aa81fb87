"""The avatar: what is drawn (Gaussians, PLY, meshes, rigs and their deformation, the demo head).

Importing this package loads nothing; each module imports what it needs.

    gaussians           a set of 3D Gaussians, as every renderer and deformer takes it
    ply                 the standard 3DGS PLY file (INRIA 3DGS and gsplat layout)
    mesh                triangle meshes of avatars: OBJ and PLY files, the fit to an avatar's box
    rig                 a rig (Gaussians + blendshapes + bones), its control layout, its deformer
    rig_deform          the deformation kernels a rig and its mesh share: quaternions, blendshapes, blended bones
    rig_file            the rig as a numpy ``.npz``: read, validated, written
    rig_mesh            the mesh a rig carries, skinned and blendshaped like its Gaussians
    demo_avatar         the built-in demo head (about 100k Gaussians) as a rig
    demo_avatar_parts   the demo head's parts: where their Gaussians sit, colours, bones
    demo_avatar_shapes  the demo head's geometry: surfaces and sampling them with Gaussians
    demo_avatar_mesh    the demo head's triangle mesh (skin, eyes, ears, neck, collar), skinned
    drivers             avatar drivers: a control vector -> posed Gaussians, frame by frame
    sources             an avatar to render: a PLY, a rig file, or a rig with a plug-in driver
"""
