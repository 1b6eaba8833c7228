tree of life
grow up and branch
