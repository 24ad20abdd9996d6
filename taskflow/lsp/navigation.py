"""(being written)"""
def definition(ctx, file, line, col):
    return None
def references(ctx, file, line, col, include_declaration):
    return None
def symbols(ctx, file):
    return None
def prepare_rename(ctx, file, line, col):
    return None
def rename(ctx, file, line, col, new_name):
    return None
