"""(being written)"""
def hover(ctx, file, line, col):
    return None
