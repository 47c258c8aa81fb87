"""What several subcommands share: the avatar options, flag names in errors, progress bars.

Importing this package loads nothing; each module imports what it needs.

    avatar_options  the options ``play`` and ``render`` share, as ``AvatarOptions``
    flags           library errors told in the command line's words (argument -> flag)
    progress        progress bars (tqdm on stderr, when it is installed and a terminal)
"""
